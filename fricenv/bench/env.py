"""Benchmark the RL environments against Pendulum-v1 and each other, side by side in one
process, with alternating rounds.

The bounds checked (ratios, so that machine speed cancels):

1. unwrapped ``StickSlipEnv.step`` at the default control interval <= 1.0x the unwrapped
   step of Gymnasium's ``Pendulum-v1``;
2. native vector env with 256 plants >= 20x cheaper per plant-step than the single env;
3. in PPO training, the environment's share of wall time < 10 %.

Timings alternate between the contenders in rounds and report medians, because the machine
may be shared. Every contender is warmed up first (numba compilation and cache loading are
excluded), and every round starts after 20 ms idle. A vector round is 200 steps (about 10
ms), so that the one-off cost of resuming after that idle (printed separately as the first
step after 20 ms idle; a few hundred microseconds on a virtual machine, where a one-thread
kernel call pays nearly as much as a two-thread one) is amortised as in a rollout, not
charged to every 50th step. The physics floor
(``core.advance_ws`` alone, per control interval, in a numba loop) is printed too: no
vector env can be cheaper per plant-step than that on one thread. So is the vector step's
numba call alone, on a twin vector env in the same rounds: the rest of the step is its
Python (action checks, copies of the results, infos). The same call on one thread, and the
machine's thread ceiling (how much faster a perfectly balanced numba loop of equal items
runs on all threads than on one), bound what threads can give: the last line of each env
shows the ratio of bound 2 that it would reach if the vector call gained the full ceiling
over its one-thread time.

Usage: ``fricenv bench env [--quick] [--no-ppo] [--json out.json] [--report-only]``. The
exit status is 1 when a bound fails (``--quick`` rounds are few and short, so a loaded
machine fails bound 2 more often than a full run does); the verdict names each failed
bound, the ratio measured and the machine's load average, and ``--report-only`` reports
them with status 0.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import json
import math
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from fricenv.bench import REPORT_ONLY_HELP, machine_load, stage, verdict
from fricenv.checks import check_output_file
from fricenv.envs import ENV_IDS, register_envs

#: Idle time before each contender's round (see ``alternating_rounds``): the 20 ms after which
#: ``_first_step_after_idle`` finds numba's workers asleep.
IDLE_S = 0.02


def _shown(ratio: float, ok: bool, at_least: bool) -> str:
    """``ratio`` to two decimals; a failing one is rounded away from its bound, so that
    a ratio just under 20 (bound: at least 20) prints 19.99, not "20.00 FAIL"."""
    if ok:
        return f"{ratio:6.2f}"
    cut = math.floor if at_least else math.ceil
    return f"{cut(ratio * 100) / 100:6.2f}"


def per_call(fn: Callable[[], None], n: int) -> float:
    """Mean seconds of ``fn()`` over ``n`` calls in a row."""
    t = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t) / n


def _actions(env, n_actions: int, seed: int) -> itertools.cycle:
    """Pre-drawn actions for ``env``, in an endless cycle; ``env`` is reset with ``seed``."""
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1, 1, (n_actions, *env.action_space.shape)).astype(np.float32)
    env.reset(seed=seed)
    return itertools.cycle(acts)


def stepper(env, n_actions: int = 512, seed: int = 0) -> Callable[[], None]:
    """A closure stepping ``env`` through pre-drawn actions (resetting when an episode ends)."""
    actions = _actions(env, n_actions, seed)

    def step() -> None:
        out = env.step(next(actions))
        if not isinstance(out[2], np.ndarray) and (out[2] or out[3]):
            env.reset()

    return step


def alternating_rounds(
    contenders: dict[str, tuple[Callable[[], None], int]], rounds: int
) -> dict[str, list[float]]:
    """Seconds per call of each contender in each round, alternating them ``rounds`` times
    (so that the i-th samples of all contenders share the machine's state of round i).

    Each round of a contender starts after IDLE_S without work, so that none inherits the
    previous one's state: numba's worker threads, still spinning just after a vector round
    (on a core that may share its hardware with the next contender's), are asleep by then,
    and a vector contender pays for waking them as a rollout does after a policy update.
    """
    samples: dict[str, list[float]] = {k: [] for k in contenders}
    for fn, n in contenders.values():
        per_call(fn, max(1, n // 10))  # warm-up: compilation, cache loading
    for _ in range(rounds):
        for name, (fn, n) in contenders.items():
            time.sleep(IDLE_S)
            samples[name].append(per_call(fn, n))
    return samples


def physics_floor(env_id: str, snapshots: int) -> float:
    """Seconds per plant-step of the physics alone, on the vector env's own plants.

    The 256 plants are stepped with random actions; after each step their parameters,
    states and core workspaces are copied and advanced by one control interval in a bare
    numba loop through ``core.advance_ws``, the call the environments make (no action
    scaling, reward, observation or Python; the excitation is not retuned, so the
    workspace's cached transition constants stay valid). No vector env on this core can
    be cheaper per plant-step than that, with one thread.
    """
    from fricenv.core import advance_ws, reset_stats
    from fricenv.envs.kernels import C_ATOL, C_RTOL, _method
    from fricenv.jit import njit as numba_njit

    njit: Any = numba_njit  # (_nrt is not in numba's typed signature)

    @njit(_nrt=False)  # as the env kernels: no reference counting of the row views
    def advance_all(P, S, stats, cfg, dt, work):
        for i in range(P.shape[0]):
            reset_stats(stats[i])
            advance_ws(P[i], S[i], dt, stats[i], _method(P[i], cfg), cfg[C_RTOL], cfg[C_ATOL],
                       10_000, work[i])

    vec: Any = gym.make_vec(env_id, num_envs=256)  # (its private buffers are read)
    step = stepper(vec, seed=1)
    total = 0.0
    P, S, stats, work = (a.copy() for a in (vec._P, vec._S, vec._stats, vec._work))
    for k in range(snapshots + 1):
        step()
        snap = (vec._P.copy(), vec._S.copy(), vec._stats.copy(), vec._work.copy())
        best = math.inf
        for _ in range(3):  # the same interval thrice from the snapshot: the fastest counts
            for dst, src in zip((P, S, stats, work), snap, strict=True):
                np.copyto(dst, src)
            t = time.perf_counter()
            advance_all(P, S, stats, vec._cfg, vec.dt, work)  # (first: compile, fill caches)
            best = min(best, time.perf_counter() - t)
        if k:
            total += best
    return total / snapshots / 256


def _kernel_stepper(vec, n_actions: int = 512, seed: int = 0,
                    serial: bool = False) -> Callable[[], None]:
    """A closure making only the numba call of ``vec.step`` (and its rare buffer refill):
    the step's cost without the Python around it (checks, copies of the results, infos).
    With ``serial``, the one-thread kernel instead of the env's own."""
    from fricenv.envs import kernels as K

    actions = _actions(vec, n_actions, seed)
    kernel = vec._serial_kernel if serial else vec._step_kernel

    def step() -> None:
        kernel(vec._table, vec._cfg, next(actions), vec._obs_pair, vec._res,
                         vec._flags, vec._counters, vec._draws, vec._bounds, vec._ivars)
        if vec._ivars[K.IV_N_EMPTY]:
            vec._refill_empty()

    return step


def thread_ceiling(rounds: int) -> tuple[float, int]:
    """This machine's speedup of a perfectly balanced numba ``prange`` loop on all its
    threads over one thread, and the thread count.

    256 equal items of about 0.4 us of arithmetic each, as the vector env's plants: no
    vector env can gain more from threads than that (a virtual machine's two vCPUs often
    give less than 2x).
    """
    from fricenv import jit  # numba through fricenv.jit: TBB and the threading layer first

    njit: Any = jit.numba.njit  # (_nrt is not in numba's typed signature)
    prange = jit.numba.prange

    @njit(_nrt=False)
    def item(x):
        s = 0.0
        for k in range(24):
            s = 0.999 * s + math.sin(x + k)
        return s

    @njit(_nrt=False)
    def serial(out):
        for i in range(out.shape[0]):
            out[i] = item(float(i))

    @njit(parallel=True, _nrt=False)
    def parallel(out):
        for i in prange(out.shape[0]):
            out[i] = item(float(i))

    out = np.zeros(256)
    samples = alternating_rounds({"serial": (lambda: serial(out), 200),
                       "parallel": (lambda: parallel(out), 200)}, rounds)
    t = {k: statistics.median(v) for k, v in samples.items()}
    return t["serial"] / t["parallel"], jit.num_threads()


def _first_step_after_idle(vec, repeats: int = 15) -> float:
    """Median seconds of one vector step after 20 ms without any (threads gone to sleep)."""
    a = np.zeros((vec.num_envs, *vec.single_action_space.shape), dtype=np.float32)
    vec.reset(seed=1)
    times = []
    for _ in range(repeats):
        time.sleep(0.02)
        t = time.perf_counter()
        vec.step(a)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def bench_steps(quick: bool) -> dict:
    rounds = 5 if quick else 15
    n_single = 2_000 if quick else 5_000
    n_vec = 50 if quick else 200
    results = {}
    pendulum = gym.make("Pendulum-v1").unwrapped
    for k, env_id in enumerate(ENV_IDS, 1):
        stage(f"step costs {k}/{len(ENV_IDS)}: {env_id} ({rounds} rounds)")
        single = gym.make(env_id).unwrapped
        made = gym.make(env_id)
        vec = gym.make_vec(env_id, num_envs=256)
        vector_step = stepper(vec)
        samples = alternating_rounds(
            {
                "pendulum": (stepper(pendulum), n_single),
                "single": (stepper(single), n_single),
                "made": (stepper(made), n_single),
                "vector": (vector_step, n_vec),
                "kernel": (_kernel_stepper(gym.make_vec(env_id, num_envs=256)), n_vec),
                "kernel_serial": (
                    _kernel_stepper(gym.make_vec(env_id, num_envs=256), serial=True), n_vec
                ),
            },
            rounds,
        )
        t = {k: statistics.median(v) for k, v in samples.items()}
        per_plant = t["vector"] / 256
        # the host's speed drifts between rounds; each round's own ratio shows the spread
        round_ratios = sorted(
            s * 256 / v for s, v in zip(samples["single"], samples["vector"], strict=True)
        )
        cold = _first_step_after_idle(vec)
        floor = physics_floor(env_id, 50 if quick else 200)
        results[env_id] = {
            "pendulum_step_us": t["pendulum"] * 1e6,
            "single_step_us": t["single"] * 1e6,
            "made_step_us": t["made"] * 1e6,
            "vector_per_plant_us": per_plant * 1e6,
            "physics_floor_us": floor * 1e6,
            "vector_first_step_after_idle_us": cold * 1e6,
            "vector_step_us": t["vector"] * 1e6,
            "vector_kernel_us": t["kernel"] * 1e6,
            "vector_kernel_serial_us": t["kernel_serial"] * 1e6,
            "single_over_pendulum": t["single"] / t["pendulum"],
            "single_over_vector_plant": t["single"] / per_plant,
            "made_over_vector_plant": t["made"] / per_plant,
            "single_over_physics_floor": t["single"] / floor,
            "single_over_vector_plant_by_round": round_ratios,
        }
    return results


@functools.cache
def _timed_class() -> type:
    """``TimedVecEnv``, built on first use: stable-baselines3 is imported only then."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class TimedVecEnv(VecEnvWrapper):
        """Adds up, in ``seconds``, the wall time spent in the wrapped VecEnv's ``reset``
        and ``step_wait`` (the environment's whole share of a rollout)."""

        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.seconds = 0.0

        def reset(self) -> Any:
            t = time.perf_counter()
            obs = self.venv.reset()
            self.seconds += time.perf_counter() - t
            return obs

        def step_wait(self) -> Any:
            t = time.perf_counter()
            out = self.venv.step_wait()
            self.seconds += time.perf_counter() - t
            return out

    return TimedVecEnv


def timed_vec_env(venv: Any) -> Any:
    """``venv`` (an SB3 ``VecEnv``) in a thin wrapper whose ``seconds`` attribute adds up
    the time spent inside its ``reset`` and ``step_wait``: what a training spends in the
    environment, the rest being the agent's (needs stable-baselines3)."""
    return _timed_class()(venv)


def bench_ppo(quick: bool) -> dict:
    """Share of PPO's wall time spent inside the VecEnv (env + adapter), after warm-up."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    env_id = "fricenv/StickSlip-v0"
    cases: dict[str, tuple[Callable[[], Any], dict[str, Any], int]] = {
        # SB3's default PPO hyperparameters on one environment.
        "single (DummyVecEnv, SB3 defaults)": (
            lambda: DummyVecEnv([lambda: gym.make(env_id)]),
            {},
            2048 * (1 if quick else 3),
        ),
        # 256 plants in one numba call; rollouts of 32 steps, minibatches of 2048.
        "native x256 (SB3 adapter)": (
            lambda: StickSlipSB3VecEnv(num_envs=256, scene="paper"),
            {"n_steps": 32, "batch_size": 2048},
            256 * 32 * (2 if quick else 6),
        ),
    }
    out = {}
    for name, (make, kwargs, steps) in cases.items():
        stage(f"PPO share: {name}, {steps} steps")
        venv = make()
        venv.reset()  # warm-up outside the timed run
        venv.step(np.zeros((venv.num_envs, *venv.action_space.shape), np.float32))
        timed = timed_vec_env(VecMonitor(venv))
        model = PPO("MlpPolicy", timed, seed=0, device="cpu", verbose=0, **kwargs)
        t = time.perf_counter()
        model.learn(steps)
        wall = time.perf_counter() - t
        out[name] = {
            "wall_s": wall,
            "env_s": timed.seconds,
            "share": timed.seconds / wall,
            "timesteps": int(model.num_timesteps),
        }
    return out


#: The bounds, each explained in one line where it is printed.
BOUND_TEXT = {
    1: "bound 1 (single / Pendulum <= 1.0): one env step costs no more than a step of "
       "Gymnasium's Pendulum-v1",
    2: "bound 2 (single / vector >= 20): the 256-plant vector env costs at least 20x less "
       "per plant-step than the single env",
    3: "bound 3 (env share < 10 %): PPO training spends under a tenth of its wall time in "
       "the environment",
}


def _glue_line(r: dict) -> str:
    """The vector step split into its numba call and the Python around it. The two are
    timed on twin envs in the same rounds; when the call alone measured slower than the
    whole step (the host was busy in some rounds), the difference is not shown, since a
    negative time means nothing."""
    glue = r["vector_step_us"] - r["vector_kernel_us"]
    python = (f"Python around it {glue:.1f} us" if glue >= 0.0 else
              "Python around it not resolved (the call alone timed slower than the whole "
              "step: the host was busy; rerun)")
    return (f"    native vector step, of which the numba call {r['vector_kernel_us']:.0f} us, "
            f"{python}")


def report_steps(steps: dict, ceiling: float, n_threads: int) -> list[str]:
    """Print the step costs and bounds 1 and 2 of each env; the bounds that fail (one line
    each, see :func:`fricenv.bench.verdict`)."""
    failed: list[str] = []
    print("step costs (medians of alternating rounds)")
    print(f"  threads: {n_threads}; a balanced numba loop runs {ceiling:.2f}x faster on them "
          "than on one (the ceiling)")
    print(f"  {BOUND_TEXT[1]}")
    print(f"  {BOUND_TEXT[2]}")
    for env_id, r in steps.items():
        print(f"  {env_id}")
        print(f"    Pendulum-v1 unwrapped step     {r['pendulum_step_us']:8.2f} us")
        print(f"    StickSlip unwrapped step       {r['single_step_us']:8.2f} us")
        print(f"    StickSlip gym.make'd step      {r['made_step_us']:8.2f} us")
        print(f"    native vector, per plant-step  {r['vector_per_plant_us']:8.3f} us (256 plants)")
        cold = r["vector_first_step_after_idle_us"]
        print(
            f"    native vector, first step after 20 ms idle {cold:.0f} us "
            f"(steady: {r['vector_step_us']:.0f} us)"
        )
        print(_glue_line(r))
        print(f"    physics alone, 1 thread        {r['physics_floor_us']:8.3f} us (floor)")
        serial_call = r["vector_kernel_serial_us"]
        gain = serial_call / r["vector_kernel_us"]
        glue = r["vector_step_us"] - r["vector_kernel_us"]
        if glue < 0.0:  # the twin's call and the env's step ran in different spells
            at_ceiling = "not computed (see above)"
        else:  # the step's Python plus its numba call with the machine's best thread gain
            best = (glue + serial_call / ceiling) / 256
            at_ceiling = f"{r['single_step_us'] / best:.1f}"
        print(
            f"    numba call on 1 thread {serial_call:.0f} us: threads gain {gain:.2f}x "
            f"(ceiling {ceiling:.2f}x); at the ceiling single / vector = {at_ceiling}"
        )
        ok1 = r["single_over_pendulum"] <= 1.0
        ok2 = r["single_over_vector_plant"] >= 20.0
        if not ok1:
            failed.append(f"bound 1 (single / Pendulum <= 1.0), {env_id}: measured "
                          f"{r['single_over_pendulum']:.2f}")
        if not ok2:
            failed.append(f"bound 2 (single / vector >= 20), {env_id}: measured "
                          f"{r['single_over_vector_plant']:.2f}")
        ratio1 = _shown(r["single_over_pendulum"], ok1, at_least=False)
        ratio2 = _shown(r["single_over_vector_plant"], ok2, at_least=True)
        print(f"    bound 1: single / Pendulum   = {ratio1}  (<= 1.0)  {'PASS' if ok1 else 'FAIL'}")
        print(
            f"    bound 2: single / vector      = {ratio2}  (>= 20)   {'PASS' if ok2 else 'FAIL'}"
            f"  [made / vector = {r['made_over_vector_plant']:.1f}; single / physics floor = "
            f"{r['single_over_physics_floor']:.1f}, the most a one-thread vector env could "
            "reach]"
        )
        by_round = r["single_over_vector_plant_by_round"]
        n_ok = sum(x >= 20.0 for x in by_round)
        print(
            f"      by round: {by_round[0]:.1f} to {by_round[-1]:.1f}, median "
            f"{statistics.median(by_round):.1f}; >= 20 in {n_ok} of {len(by_round)} rounds"
        )
    return failed


def report_ppo(ppo: dict) -> list[str]:
    """Print bound 3 for each PPO setup; the bounds that fail (one line each)."""
    print(f"PPO training: {BOUND_TEXT[3]}")
    failed: list[str] = []
    for name, r in ppo.items():
        ok = r["share"] < 0.10
        if not ok:
            failed.append(f"bound 3 (env share < 10 %), {name}: measured "
                          f"{r['share'] * 100:.1f} %")
        print(
            f"  {name:36s} {r['share'] * 100:5.1f} %  ({r['env_s']:.2f} s of "
            f"{r['wall_s']:.1f} s, {r['timesteps']} steps)  {'PASS' if ok else 'FAIL'}"
        )
    return failed


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog=prog, description="Environment step costs against Pendulum-v1, the vector "
        "env's gain, and PPO's share of time in the env.",
        epilog="example:\n  fricenv bench env --quick --no-ppo --json out/env.json",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer and shorter rounds")
    ap.add_argument("--no-ppo", action="store_true", help="skip the PPO share measurement")
    ap.add_argument("--json", help="write the results to this file")
    ap.add_argument("--report-only", action="store_true", help=REPORT_ONLY_HELP)
    return ap


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """Run the benchmark; the exit status is 1 when a bound fails."""
    ap = build_parser(prog)
    args = ap.parse_args(argv)
    if args.json:
        try:  # before the benchmark, not after minutes of it
            check_output_file("--json", args.json)
        except ValueError as e:
            ap.error(str(e))
    register_envs()

    steps = bench_steps(args.quick)
    stage("thread ceiling: a balanced numba loop on one thread and on all")
    ceiling, n_threads = thread_ceiling(5 if args.quick else 15)
    failed = report_steps(steps, ceiling, n_threads)
    results = {"steps": steps, "thread_ceiling": ceiling, "threads": n_threads}
    if not args.no_ppo:
        ppo = bench_ppo(args.quick)
        results["ppo"] = ppo
        failed += report_ppo(ppo)
    results["failed_bounds"] = failed
    results["machine_load"] = machine_load()
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2)
    return verdict(failed, args.report_only)


if __name__ == "__main__":
    raise SystemExit(main())
