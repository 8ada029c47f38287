"""Train a stick-slip suppression agent with stable-baselines3.

    python -m fricenv_agents.train --algo ppo --scene self_excited --seed 0 -n 300000

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` (rl-baselines3-zoo style, one
entry per environment id, i.e. per scene); ``-params key:value`` overrides single entries.
Each run writes its own folder, by default ``out/runs/<algo>_<scene>_s<seed>_<timestamp>/``:

- ``config.yml``: everything needed to repeat the run (resolved hyperparameters, seeds,
  versions, command line) and the measured training wall time;
- ``model.zip`` and ``vecnormalize.pkl`` (if observations/rewards are normalised);
- ``evaluations.npz`` / ``eval_log.csv``: periodic deterministic evaluation on fixed
  episodes (return, stick fraction, effort) -- the learning curve;
- ``monitor.csv`` (training episodes) and ``progress.csv`` (SB3 logger); TensorBoard
  events under ``tb/`` with ``--tensorboard``.

Training runs on the native vector environment (``StickSlipSB3VecEnv``: all plants in one
numba call). Training plants are seeded ``1000 * seed + i`` and the periodic evaluation
``1000 * seed + 500 + i``; final evaluations use seeds from 10,000,000 on, so no reported
episode was ever trained on.
"""

from __future__ import annotations

import argparse
import contextlib
import platform
import shlex
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from fricenv.checks import check_output_dir
from fricenv.interrupts import sigterm_handled

from .cli import HelpFormatter, Stages
from .config import (
    RunSpec,
    apply_overrides,
    check_hyperparams,
    load_hyperparams,
    split_hyperparams,
)
from .envs import make_sb3_env
from .layout import (
    ALGOS,
    MAX_PLANTS,
    SCENE_ENV_IDS,
    algo_class,
    callback_env_seed,
    check_seed,
    train_env_seed,
)


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog or "python -m fricenv_agents.train", description=__doc__.split("\n\n")[0],
        formatter_class=HelpFormatter)
    p.add_argument("--algo", required=True, choices=ALGOS, help="RL algorithm")
    p.add_argument("--scene", required=True, choices=sorted(SCENE_ENV_IDS), help="scene")
    p.add_argument("--seed", type=int, default=0, help="seeds torch, the policy and the envs")
    p.add_argument("-n", "--n-timesteps", type=int, default=None,
                   help="training steps (default: the hyperparameter file's n_timesteps)")
    p.add_argument("--hyperparams", type=Path, default=None,
                   help="hyperparameter yml (default: the <algo>.yml shipped in "
                        "fricenv_agents/hyperparams)")
    p.add_argument("-params", "--params", nargs="+", default=[], metavar="KEY:VALUE",
                   help="override hyperparameters, e.g. -params n_envs:8 gamma:0.98")
    p.add_argument("-f", "--log-folder", type=Path, default=Path("out/runs"),
                   help="parent folder of the run folder")
    p.add_argument("--run-dir", type=Path, default=None,
                   help="exact run folder (default: <log-folder>/<algo>_<scene>_s<seed>_<time>)")
    p.add_argument("--eval-freq", type=int, default=10_000,
                   help="evaluate every this many steps, and at the start and the end (0: "
                        "at the start and the end only)")
    p.add_argument("--eval-episodes", type=int, default=16, help="episodes per evaluation")
    p.add_argument("--tensorboard", action="store_true",
                   help="also log to TensorBoard (<run>/tb; needs the tensorboard package)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar, stage lines or compile notice on stderr")
    p.add_argument("--threads", type=int, default=1,
                   help="torch threads (small MLPs train fastest on one)")
    return p


def _check_folders(args: argparse.Namespace) -> None:
    """``ValueError`` for a --run-dir that holds anything, or a folder option that is (or
    lies in) a file (before any work, so that a rerun needs nothing cleaned up)."""
    for flag, path in (("--run-dir", args.run_dir), ("-f", args.log_folder)):
        if path is not None:
            check_output_dir(flag, path)
    if args.run_dir is not None and args.run_dir.exists() and any(args.run_dir.iterdir()):
        raise ValueError(f"run folder {args.run_dir} exists and is not empty")


class SetupError(ValueError):
    """The environment or model could not be built from the hyperparameters (the run folder
    made for it has been removed again)."""


class TrainingError(RuntimeError):
    """Training stopped with an exception; the unfinished run folder (no model) has been
    removed so that it neither blocks a rerun nor passes for a run."""


def _discard(run_dir: Path, existed: bool) -> None:
    """Remove an unfinished run folder; a --run-dir the user made (empty: ``prepare``
    checked) is remade, empty."""
    shutil.rmtree(run_dir, ignore_errors=True)
    if existed:
        run_dir.mkdir()


def _run_dir(args: argparse.Namespace) -> Path:
    if args.run_dir is not None:  # (checked empty by ``prepare``)
        path = args.run_dir
    else:
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        base = args.log_folder / f"{args.algo}_{args.scene}_s{args.seed}_{stamp}"
        path, k = base, 1
        while path.exists():
            path = base.with_name(f"{base.name}_{k}")
            k += 1
    path.mkdir(parents=True, exist_ok=True)
    return path


def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    import fricenv

    return {"python": platform.python_version(), "numpy": np.__version__,
            "torch": str(torch.__version__), "stable_baselines3": stable_baselines3.__version__,
            "gymnasium": gymnasium.__version__, "fricenv": fricenv.__version__}


def _plain(value: Any) -> Any:
    """YAML-safe copy of a hyperparameter entry (callables and classes as their names)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return getattr(value, "__name__", repr(value))


def prepare(args: argparse.Namespace) -> tuple[RunSpec, dict[str, Any], Path]:
    """Check the command line and resolve the hyperparameters (``ValueError`` if bad)."""
    check_seed(args.seed)
    if args.threads < 1:
        raise ValueError(f"--threads must be >= 1, got {args.threads}")
    if args.n_timesteps is not None and args.n_timesteps < 1:
        raise ValueError(f"-n must be >= 1, got {args.n_timesteps}")
    if not 1 <= args.eval_episodes <= MAX_PLANTS or args.eval_freq < 0:
        # (more episodes would reach the next run's block of plant seeds)
        raise ValueError(f"need 1 <= --eval-episodes <= {MAX_PLANTS} and --eval-freq >= 0, "
                         f"got {args.eval_episodes} and {args.eval_freq}")
    _check_folders(args)
    if args.tensorboard:
        try:
            import tensorboard  # noqa: F401
        except ImportError:
            raise ValueError("--tensorboard needs the tensorboard package "
                             "(pip install tensorboard)") from None
    hp_file = args.hyperparams or Path(__file__).resolve().parent / "hyperparams" / (
        f"{args.algo}.yml")
    if not hp_file.exists():
        raise ValueError(f"hyperparameter file {hp_file} does not exist")
    raw = apply_overrides(load_hyperparams(args.algo, args.scene, hp_file), args.params)
    if args.n_timesteps is not None:
        raw["n_timesteps"] = args.n_timesteps
    raw = check_hyperparams(args.algo, raw)  # (config.yml records checked numbers)
    return split_hyperparams(args.algo, raw), raw, hp_file


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped a training; ``signum`` is the signal. A
    ``KeyboardInterrupt``, so that whatever stops on Ctrl-C stops on it too."""

    def __init__(self, message: str = "", signum: int = signal.SIGINT) -> None:
        super().__init__(message)
        self.signum = signum


def _raise_on_sigterm(signum: int, frame: object) -> None:
    raise TrainingInterrupted(f"stopped by {signal.Signals(signum).name}", signum)


@contextlib.contextmanager
def sigterm_as_ctrl_c() -> Iterator[None]:
    """Within this block SIGTERM stops a training as Ctrl-C does (the model so far saved,
    config.yml marked interrupted), as ``fricenv.calls.sweep_signals`` does for sweeps."""
    with sigterm_handled(_raise_on_sigterm):
        yield


def train(args: argparse.Namespace, prepared: tuple | None = None,
          stage: Callable[[str], None] | None = None) -> Path:
    """Run one training; returns the run folder. ``stage``: called with a line per stage
    (building, training, saving). Ctrl-C, or SIGTERM, during training saves the model so
    far and raises :class:`TrainingInterrupted` (a ``KeyboardInterrupt``)."""
    with sigterm_as_ctrl_c():
        return _train(args, prepared, stage)


def _train(args: argparse.Namespace, prepared: tuple | None,
           stage: Callable[[str], None] | None) -> Path:
    stage = stage or (lambda message: None)
    spec, raw, hp_file = prepared or prepare(args)
    stage(f"building {spec.n_envs} environment{'s' if spec.n_envs > 1 else ''} of scene "
          f"{args.scene} and the {args.algo.upper()} model (torch, stable-baselines3)")
    import torch
    from stable_baselines3.common.logger import Logger, make_output_format
    from stable_baselines3.common.vec_env import VecNormalize

    seed = args.seed
    existed = args.run_dir is not None and args.run_dir.exists()
    run_dir = _run_dir(args)

    torch.set_num_threads(args.threads)
    try:  # hyperparameters only the constructors check (env kwargs, normalize, policy)
        env = make_sb3_env(args.scene, spec.n_envs, train_env_seed(seed), spec.env_kwargs,
                           monitor_file=run_dir / "monitor.csv")
        if spec.normalize is not None:
            gamma = spec.algo_kwargs.get("gamma", 0.99)
            env = VecNormalize(env, gamma=gamma, **spec.normalize)
        model = algo_class(args.algo)(spec.policy, env, seed=seed, device="cpu", verbose=0,
                                      **spec.algo_kwargs)
    except KeyboardInterrupt:
        _discard(run_dir, existed)  # nothing trained yet: nothing to keep
        raise
    except Exception as e:
        # leave nothing behind that would block the corrected rerun or look like a run
        _discard(run_dir, existed)
        raise SetupError(f"cannot build the training from these hyperparameters: "
                         f"{type(e).__name__}: {e}") from e
    # SB3 seeds the env with ``seed`` itself while building the model (plants seed + i);
    # put back the run's own block of plant seeds, which config.yml records.
    env.seed(train_env_seed(seed))
    outputs = [make_output_format("csv", str(run_dir))]
    if args.tensorboard:
        outputs.append(make_output_format("tensorboard", str(run_dir / "tb")))
    model.set_logger(Logger(str(run_dir), outputs))

    from .runs import observation_names, portable_path

    config = {
        "algo": args.algo, "scene": args.scene, "env_id": SCENE_ENV_IDS[args.scene],
        "seed": seed, "n_timesteps": spec.n_timesteps, "n_envs": spec.n_envs,
        "hyperparams_file": portable_path(hp_file), "overrides": list(args.params),
        "hyperparams": _plain(raw), "env_kwargs": spec.env_kwargs,
        "observation": observation_names(args.scene, spec.env_kwargs),
        "normalize": spec.normalize, "train_env_seeds": [train_env_seed(seed),
                                                         train_env_seed(seed) + spec.n_envs - 1],
        "eval_callback_seeds": [callback_env_seed(seed),
                                callback_env_seed(seed) + args.eval_episodes - 1],
        "eval_freq": args.eval_freq, "eval_episodes": args.eval_episodes,
        "command": getattr(args, "command_line", None) or command_line(None, None),
        "versions": _versions(), "started": datetime.now().isoformat(timespec="seconds"),
        "torch_threads": torch.get_num_threads(),
    }
    cfg_path = run_dir / "config.yml"
    cfg_path.write_text(yaml.safe_dump(config, sort_keys=False))

    if spec.warm_start is not None:
        config["warm_start"] = _warm_start(model, env, args, spec, stage)
        cfg_path.write_text(yaml.safe_dump(config, sort_keys=False))

    from .callbacks import PeriodicEval, ProgressBar

    status: dict[str, Any] = {}
    evaluator = PeriodicEval(args.scene, spec.env_kwargs, callback_env_seed(seed),
                             args.eval_episodes, args.eval_freq, run_dir, status)
    bar = ProgressBar(spec.n_timesteps, status,
                      enabled=not (args.no_progress or getattr(args, "quiet", False)))
    when = (f"first, every {args.eval_freq} steps and last" if args.eval_freq
            else "first and last")
    stage(f"training {spec.n_timesteps} steps into {run_dir}; evaluating on "
          f"{args.eval_episodes} episodes {when}")
    t0 = time.perf_counter()
    stopped_by: int | None = None
    try:
        model.learn(spec.n_timesteps, callback=[evaluator, bar])
    except KeyboardInterrupt as e:
        # Ctrl-C (or SIGTERM), the usual way to end a long run early: keep what was
        # trained (as rl-baselines3-zoo does); config.yml records the stop and the steps.
        stopped_by = int(getattr(e, "signum", signal.SIGINT))
        if bar.bar is not None:
            bar.bar.close()
    except Exception as e:  # (as a failed setup: a half-written folder would block a rerun)
        model.logger.close()
        env.close()
        _discard(run_dir, existed)
        raise TrainingError(f"training failed after {model.num_timesteps} steps "
                            f"({type(e).__name__}: {e}); removed the unfinished run folder "
                            f"{run_dir}") from e
    train_seconds = time.perf_counter() - t0
    with _deferred_sigterm():  # a second SIGTERM must not cut the save short
        _save(model, env, run_dir, spec, config, cfg_path, evaluator, train_seconds,
              stopped_by, stage)
    if stopped_by is not None:
        raise TrainingInterrupted(f"training interrupted after {model.num_timesteps} steps "
                                  f"by {signal.Signals(stopped_by).name}; the model trained "
                                  f"so far is saved in {run_dir}", stopped_by)
    return run_dir


@contextlib.contextmanager
def _deferred_sigterm() -> Iterator[None]:
    """SIGTERM ignored within the block where it was our own handler's: the model being
    saved is what the first signal asked for."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not _raise_on_sigterm):
        yield
        return
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, _raise_on_sigterm)


def _save(model: Any, env: Any, run_dir: Path, spec: RunSpec, config: dict, cfg_path: Path,
          evaluator: Any, train_seconds: float, stopped_by: int | None,
          stage: Callable[[str], None]) -> None:
    """Save the model, its normalisation and the finished config (``stopped_by``: the
    signal that ended the training early, recorded as ``interrupted``)."""
    stage("saving the model")
    model.save(run_dir / "model.zip")
    if spec.normalize is not None:
        env.save(str(run_dir / "vecnormalize.pkl"))
    env.close()
    # (an interrupted run's last evaluation may predate its last steps: eval_log.csv has
    # its timesteps; with a stop during the first evaluation there is none)
    last = evaluator.rows[-1] if evaluator.rows else None
    config.update({
        "finished": datetime.now().isoformat(timespec="seconds"),
        "train_seconds": round(train_seconds, 2), "timesteps_done": int(model.num_timesteps),
        "final_eval": None if last is None else {
            k: last[k] for k in ("return_mean", "stick_fraction", "effort")},
    })
    if stopped_by is not None:
        config["interrupted"] = True
        config["stopped_by"] = signal.Signals(stopped_by).name
    cfg_path.write_text(yaml.safe_dump(config, sort_keys=False))
    print(f"run folder: {run_dir}\ntraining wall time: {train_seconds:.1f} s "
          f"({model.num_timesteps} of {spec.n_timesteps} steps)" + (
              "" if last is None else f"; last eval return {last['return_mean']:.3f}, "
              f"stick fraction {last['stick_fraction']:.4f}"))


def _warm_start(model: Any, env: Any, args: argparse.Namespace, spec: RunSpec,
                stage: Callable[[str], None]) -> dict[str, Any]:
    """DAgger from the MPC (``fricenv_agents.imitation``) before PPO; its summary, with the
    wall time, for config.yml. Its plants are the run's own training plants."""
    from .imitation import WarmStart, dagger

    settings = WarmStart.from_mapping(spec.warm_start)
    stage(f"warm-starting from the MPC: {settings.rounds} DAgger rounds")
    t0 = time.perf_counter()
    summary = dagger(model, env, args.scene, spec.env_kwargs, settings, args.seed,
                     log=None if getattr(args, "quiet", False) else print)
    env.seed(train_env_seed(args.seed))  # PPO starts on the run's own plants, as without it
    return {**summary, "seconds": round(time.perf_counter() - t0, 2)}


def command_line(argv: Sequence[str] | None, prog: str | None) -> str:
    """The shell command that repeats this run, for config.yml: the program as it was
    started (``fricenv train`` or ``python -m fricenv_agents.train``) and its arguments,
    quoted, without the ``fricenv`` command's own ``train``."""
    words = list(sys.argv[1:] if argv is None else argv)
    return shlex.join([*(prog or "python -m fricenv_agents.train").split(), *words])


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> Path:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    args.command_line = command_line(argv, prog)
    stage = Stages(parser.prog, args.quiet)
    stage("checking the hyperparameters (loads torch and stable-baselines3)")
    try:
        prepared = prepare(args)
    except ValueError as e:  # bad input: a clear message and exit status 2, as argparse does
        parser.error(str(e))
    try:
        return train(args, prepared, stage)
    except SetupError as e:
        parser.error(str(e))
    except TrainingError as e:  # not a usage error, but no traceback of SB3's insides
        parser.exit(1, f"{parser.prog}: error: {e}\n")
    except KeyboardInterrupt as e:  # (the shell's status for a signal: 128 + its number)
        parser.exit(128 + int(getattr(e, "signum", signal.SIGINT)),
                    f"{parser.prog}: {e or 'interrupted'}\n")


if __name__ == "__main__":
    main()
