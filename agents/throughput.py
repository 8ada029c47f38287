"""Throughput as the control benchmark runs it: the native vector environment's plant-steps
per second at several plant counts, and PPO's samples per second with SB3, with the share
of the training's wall time spent inside the environment.

    python -m fricenv_agents.throughput [--scenes ...] [--plants 1 16 256 4096]
                                        [--ppo-steps N] [--out DIR]

**Vector environment.** For each scene, one ``StickSlipVectorEnv`` per plant count, with
the ``env_kwargs`` of the scene's entry in ``hyperparams/ppo.yml`` and same-step autoreset
(as the SB3 adapter trains on it), reset with seed 0 (plant i seeded i). Each is stepped as
the environment benchmark (``fricenv bench env``) steps it, with its own helpers
(``fricenv.bench.env.stepper`` and ``alternating_rounds``): 512 actions drawn before any
timing, uniform in [-1, 1] from ``numpy.random.default_rng(0)``, cycled; a warm-up first
(numba compilation or cache loading are not timed); then ``rounds`` rounds alternating the
plant counts, each after 20 ms idle (as a rollout resumes after a policy update) and of
about ``ROUND_S`` seconds. Reported: plant-steps per second, the plants over the median
seconds per step of the rounds, and those of the slowest and the fastest round. From
``PARALLEL_MIN_ENVS`` plants on, a step spreads the plants over numba's threads.

**PPO.** For each scene, PPO with the scene's entry in ``hyperparams/ppo.yml``, built as
``python -m fricenv_agents.train`` builds it: its ``n_envs`` plants (16) of the native SB3
vector env, monitored and seeded as in training, ``VecNormalize`` as configured, torch on
one thread (training's default ``--threads``), on the CPU. The env is reset and stepped
once before, so that loading the kernels is not timed; then ``learn(ppo_steps)`` is timed
(SB3 runs whole rollouts of ``n_steps * n_envs`` samples, so it rounds ``ppo_steps`` up;
the default is ``PPO_ROLLOUTS`` rollouts). Samples per second = timesteps / wall time. A
thin timing wrapper (``fricenv.bench.env.timed_vec_env``) between the monitored env and
``VecNormalize`` adds up the time spent in the env's ``reset`` and ``step_wait``: the
native step, the SB3 adapter's infos and ``VecMonitor``. That is the env's share; the rest
of the wall time is the agent's: policy inference during the rollouts, ``VecNormalize``'s
running statistics, the rollout buffer and the PPO update (``n_epochs`` passes over the
rollout in minibatches).

The result (``measure``) is a JSON-able dict that also records the machine (CPU count,
numba's threading layer and threads, the load average before and after, versions); a
shared machine slows every number, so read them with its load. ``markdown`` turns it into
the tables of the benchmark page. ``--out DIR`` writes ``throughput.json`` and
``throughput.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fricenv.checks import check_int, check_output_dir

from .cli import HelpFormatter, Stages
from .config import load_hyperparams, split_hyperparams
from .layout import SCENE_ENV_IDS, check_scene, train_env_seed

#: The plant counts measured by default.
PLANTS = (1, 16, 256, 4096)
#: Timed rounds per plant count (their median is reported, and the slowest and fastest).
ROUNDS = 5
#: Seconds a timed round of one plant count lasts, about: long enough that the clock's
#: resolution and the wake-up after the idle before it are small beside it.
ROUND_S = 0.05
#: PPO rollouts timed by default (each ``n_steps * n_envs`` samples and one update).
PPO_ROLLOUTS = 3
#: torch threads during the PPO timing, as ``train --threads`` by default.
TORCH_THREADS = 1


def _stage_or_silent(stage: Callable[[str], None] | None) -> Callable[[str], None]:
    return stage or (lambda message: None)


def _cpu_name() -> str:
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else ``platform.processor()``."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _load_average() -> float | None:
    """The 1-minute load average (None where the system has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


def machine() -> dict[str, Any]:
    """What the numbers depend on: CPU, threads, numba's threading layer, versions."""
    import numba

    from fricenv.jit import threading_info

    from .train import _versions

    info = threading_info()
    usable = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    return {
        "cpu": _cpu_name(), "cpu_count": os.cpu_count(),
        "cpus_usable": None if usable is None else len(usable),
        "platform": platform.platform(), "numba_threading_layer": info.layer,
        "numba_threads": info.num_threads, "torch_threads": TORCH_THREADS,
        "versions": {**_versions(), "numba": numba.__version__},
    }


def _check_plants(plants: Sequence[int]) -> list[int]:
    from fricenv.envs.vector import MAX_NUM_ENVS

    if isinstance(plants, (str, bytes)) or not isinstance(plants, Sequence) or not plants:
        raise ValueError(f"plants must be a non-empty sequence of ints, got {plants!r}")
    counts = [check_int("plants", n, 1, MAX_NUM_ENVS) for n in plants]
    if len(set(counts)) != len(counts):
        raise ValueError(f"plants must not repeat a count, got {list(plants)!r}")
    return counts


def _check_scenes(scenes: Sequence[str]) -> list[str]:
    if isinstance(scenes, (str, bytes)) or not isinstance(scenes, Sequence) or not scenes:
        raise ValueError(f"scenes must be a non-empty sequence of scene names, got {scenes!r}")
    for scene in scenes:
        check_scene(scene)
    if len(set(scenes)) != len(scenes):
        raise ValueError(f"scenes must not repeat a scene, got {list(scenes)!r}")
    return list(scenes)


def vector_rates(scene: str, plants: Sequence[int], rounds: int = ROUNDS) -> list[dict]:
    """One row per plant count: plant-steps per second of the scene's native vector env
    (plants / the median seconds per step of ``rounds`` alternating rounds), and those of
    the slowest and the fastest round."""
    from gymnasium.vector import AutoresetMode

    from fricenv.bench.env import alternating_rounds, per_call, stepper
    from fricenv.envs.vector import StickSlipVectorEnv

    env_kwargs = split_hyperparams("ppo", load_hyperparams("ppo", scene)).env_kwargs
    envs = {n: StickSlipVectorEnv(num_envs=n, autoreset_mode=AutoresetMode.SAME_STEP, scene=scene,
                                  **env_kwargs) for n in plants}
    try:
        contenders = {}
        for n, venv in envs.items():
            step = stepper(venv, seed=0)  # (actions drawn here; resets with seed 0)
            step()  # the first call compiles or loads the kernels
            calls = max(3, math.ceil(ROUND_S / per_call(step, 3)))
            contenders[str(n)] = (step, calls)
        samples = alternating_rounds(contenders, rounds)
    finally:
        for venv in envs.values():
            venv.close()
    rows = []
    for n in plants:
        seconds = samples[str(n)]  # per step, one a round
        median_s = statistics.median(seconds)
        rows.append({"scene": scene, "plants": n, "plant_steps_per_s": n / median_s,
                     "slowest_round": n / max(seconds), "fastest_round": n / min(seconds),
                     "step_us": median_s * 1e6, "rounds": rounds,
                     "steps_per_round": contenders[str(n)][1]})
    return rows


def ppo_rate(scene: str, ppo_steps: int | None = None, seed: int = 0) -> dict[str, Any]:
    """PPO's samples per second on ``scene`` and the env's share of the wall time, over
    ``learn(ppo_steps)`` (None: ``PPO_ROLLOUTS`` rollouts) built as ``train`` builds it."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from fricenv.bench.env import timed_vec_env

    from .envs import make_sb3_env

    spec = split_hyperparams("ppo", load_hyperparams("ppo", scene))
    threads = torch.get_num_threads()
    torch.set_num_threads(TORCH_THREADS)
    venv = make_sb3_env(scene, spec.n_envs, train_env_seed(seed), spec.env_kwargs)
    try:
        venv.reset()  # kernels loaded outside the timing
        venv.step(np.zeros((venv.num_envs, *venv.action_space.shape), np.float32))
        timed = timed_vec_env(venv)
        env = timed if spec.normalize is None else VecNormalize(
            timed, gamma=spec.algo_kwargs.get("gamma", 0.99), **spec.normalize)
        model = PPO(spec.policy, env, seed=seed, device="cpu", verbose=0, **spec.algo_kwargs)
        env.seed(train_env_seed(seed))  # (as train: the run's own block of plant seeds)
        rollout = model.n_steps * model.n_envs
        steps = PPO_ROLLOUTS * rollout if ppo_steps is None else ppo_steps
        timed.seconds = 0.0
        t = time.perf_counter()
        model.learn(steps)
        wall = time.perf_counter() - t
    finally:
        torch.set_num_threads(threads)
        venv.close()
    done = int(model.num_timesteps)
    return {"scene": scene, "n_envs": int(model.n_envs), "n_steps": int(model.n_steps),
            "normalize": spec.normalize is not None, "timesteps": done,
            "rollouts": done // rollout, "wall_s": wall, "env_s": timed.seconds,
            "samples_per_s": done / wall, "env_share": timed.seconds / wall,
            "env_samples_per_s": done / timed.seconds}


def measure(scenes: Sequence[str] = tuple(SCENE_ENV_IDS), plants: Sequence[int] = PLANTS,
            ppo_steps: int | None = None, rounds: int = ROUNDS,
            stage: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Measure the vector env's plant-steps per second on ``scenes`` at each plant count of
    ``plants``, and PPO's samples per second on each scene over ``ppo_steps`` steps (None:
    ``PPO_ROLLOUTS`` rollouts; 0: no PPO). A JSON-able dict: ``machine``, ``vector`` and
    ``ppo`` (a list of rows each), ``seconds``. Bad arguments are a ``ValueError``."""
    scenes = _check_scenes(scenes)
    plants = _check_plants(plants)
    rounds = check_int("rounds", rounds, 1, 10_000)
    if ppo_steps is not None:
        ppo_steps = check_int("ppo_steps", ppo_steps, 0, 10**9)
    say = _stage_or_silent(stage)
    t0 = time.perf_counter()
    load_before = _load_average()
    result: dict[str, Any] = {"machine": machine(), "vector": [], "ppo": []}
    for scene in scenes:
        say(f"vector env of {scene}: {', '.join(map(str, plants))} plants, {rounds} rounds")
        result["vector"] += vector_rates(scene, plants, rounds)
    if ppo_steps != 0:
        for scene in scenes:
            say(f"PPO on {scene}" + ("" if ppo_steps is None else f", {ppo_steps} steps"))
            result["ppo"].append(ppo_rate(scene, ppo_steps))
    result["machine"]["load_average_1min"] = [load_before, _load_average()]
    result["seconds"] = round(time.perf_counter() - t0, 1)
    return result


def _machine_line(m: dict[str, Any]) -> str:
    v = m["versions"]
    load = " to ".join("?" if x is None else f"{x:.2f}" for x in m["load_average_1min"])
    return (f"Measured on {m['cpu']} ({m['cpu_count']} CPUs, {m['cpus_usable']} usable; "
            f"numba {v['numba']} on its {m['numba_threading_layer']} threading layer with "
            f"{m['numba_threads']} threads; 1-minute load average {load} from start to end), "
            f"fricenv {v['fricenv']}, numpy {v['numpy']}, torch {v['torch']}, "
            f"stable-baselines3 {v['stable_baselines3']}, Python {v['python']}.")


def markdown(result: dict[str, Any]) -> list[str]:
    """The result as Markdown lines for the benchmark page: a paragraph on the machine and
    how it was measured, a table of the vector env's rates, one of PPO's."""
    lines = ["### Throughput", "",
             "Made by `python -m fricenv_agents.throughput` (see its docstring). "
             + _machine_line(result["machine"]), ""]
    vector = result["vector"]
    if vector:
        lines += ["Native vector env (`StickSlipVectorEnv`), random actions drawn before "
                  "the timing, median of alternating rounds after a warm-up:", "",
                  "| scene | plants | plant-steps/s | slowest–fastest round | µs per step |",
                  "|---|---:|---:|---:|---:|"]
        lines += [f"| {r['scene']} | {r['plants']} | {r['plant_steps_per_s']:,.0f} | "
                  f"{r['slowest_round']:,.0f}–{r['fastest_round']:,.0f} | "
                  f"{r['step_us']:,.1f} |" for r in vector]
        lines.append("")
    ppo = result["ppo"]
    if ppo:
        lines += ["PPO (stable-baselines3) with `hyperparams/ppo.yml`, one torch thread; the "
                  "env's share is the time in its `reset` and `step_wait` (native step, SB3 "
                  "adapter, `VecMonitor`), the rest is policy inference, `VecNormalize`, the "
                  "rollout buffer and the PPO update:", "",
                  "| scene | plants | samples/s | env share | env samples/s | timesteps | "
                  "wall s |", "|---|---:|---:|---:|---:|---:|---:|"]
        lines += [f"| {r['scene']} | {r['n_envs']} | {r['samples_per_s']:,.0f} | "
                  f"{r['env_share'] * 100:.1f} % | {r['env_samples_per_s']:,.0f} | "
                  f"{r['timesteps']} | {r['wall_s']:.1f} |" for r in ppo]
        lines.append("")
    return lines


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog or "python -m fricenv_agents.throughput",
        description=__doc__.split("\n\n")[0], formatter_class=HelpFormatter)
    p.add_argument("--scenes", nargs="+", choices=sorted(SCENE_ENV_IDS),
                   default=list(SCENE_ENV_IDS), metavar="SCENE",
                   help=f"scenes, of {', '.join(sorted(SCENE_ENV_IDS))}")
    p.add_argument("--plants", nargs="+", type=int, default=list(PLANTS), metavar="N",
                   help="plant counts of the vector env")
    p.add_argument("--ppo-steps", type=int, default=None, metavar="N",
                   help=f"PPO steps per scene, rounded up to whole rollouts (default: "
                        f"{PPO_ROLLOUTS} rollouts; 0: no PPO)")
    p.add_argument("--rounds", type=int, default=ROUNDS, metavar="N",
                   help="timed rounds per plant count")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="write throughput.json and throughput.md into this folder")
    p.add_argument("--quiet", action="store_true", help="no stage lines on stderr")
    return p


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> dict[str, Any]:
    """Measure, print the Markdown tables, and write them with the JSON to ``--out``."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    try:
        if args.out is not None:  # (before minutes of measuring, not after)
            check_output_dir("--out", args.out)
        result = measure(args.scenes, args.plants, args.ppo_steps, args.rounds,
                         Stages(parser.prog, args.quiet))
    except ValueError as e:
        parser.error(str(e))
    lines = markdown(result)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "throughput.json").write_text(json.dumps(result, indent=1))
        (args.out / "throughput.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return result


if __name__ == "__main__":
    main()
