"""Train every policy of the control benchmark (``fricenv_agents.benchmark``), a few at a time.

    python scripts/train_control_benchmark.py [--jobs 2] [--seeds 5] [--robust-seeds 5]
        [--groups ppo ppo_robust sac] [--scenes paper self_excited stribeck viscous]
        [--root agents/pretrained/benchmark] [--dry-run]

Each run is ``python -m fricenv_agents.train`` with the hyperparameter file's entry for its
scene, into ``<root>/<group>_<scene>_s<seed>``. The groups are the benchmark's trained
rows (``fricenv_agents.benchmark.ROWS``, each with its algorithm and env kwargs): ``ppo``,
``sac``, and ``ppo_robust``, PPO trained on randomised plants with sensor noise and delay
drawn per episode (``ROBUST_ENV_KWARGS``: ``ROBUST_NOISE_FACTOR`` times the benchmark's
``NOISE``, scaled per episode by a draw in [0, 1), and a delay of 0 or 1 interval). A run
whose folder holds a model is skipped; a folder without one (a run cut off) is removed and
the run started again, so the command can simply be repeated until all are done. Logs go
to ``<root>/logs``. Runs use one torch thread each (``--threads 1``).

The default root is the folder of run folders the package ships and the benchmark reads
by default, so that from a clean clone this command has nothing to do and ``python -m
fricenv_agents.benchmark`` evaluates the shipped models; the folder's ``.gitignore`` keeps
the training logs out of the repository. Train elsewhere (``--root out/runs/control``) and
pass ``--runs`` to the benchmark to compare fresh runs.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from fricenv_agents.benchmark import BENCH_SCENES as SCENES
from fricenv_agents.benchmark import training_groups

#: Group -> (algorithm, env kwargs), from the benchmark's rows.
GROUPS: dict[str, tuple[str, dict[str, Any]]] = training_groups()
ROBUST = "ppo_robust"  #: the group ``--robust-seeds`` counts the seeds of
POLL_S = 5.0


def train_args(env_kwargs: dict[str, Any]) -> list[str]:
    """The ``-params`` override of a group's env kwargs (JSON is YAML's flow style)."""
    return ["-params", "env_kwargs:" + json.dumps(env_kwargs)] if env_kwargs else []


def jobs(groups: list[str], scenes: list[str], seeds: int, robust_seeds: int,
         root: Path) -> list[tuple[Path, list[str]]]:
    """(run folder, command) of every run, groups in the order given, then seeds."""
    out = []
    for group in groups:
        algo, env_kwargs = GROUPS[group]
        extra = train_args(env_kwargs)
        n = robust_seeds if group == ROBUST else seeds
        for seed in range(n):
            for scene in scenes:
                run = root / f"{group}_{scene}_s{seed}"
                cmd = [sys.executable, "-m", "fricenv_agents.train", "--algo", algo,
                       "--scene", scene, "--seed", str(seed), "--run-dir", str(run),
                       "--no-progress", "--threads", "1", *extra]
                out.append((run, cmd))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--jobs", type=int, default=2, help="runs at a time")
    p.add_argument("--seeds", type=int, default=5,
                   help=f"training seeds of every group but {ROBUST}")
    p.add_argument("--robust-seeds", type=int, default=5, help=f"training seeds of {ROBUST}")
    p.add_argument("--groups", "--algos", nargs="+", choices=sorted(GROUPS),
                   default=list(GROUPS))
    p.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    p.add_argument("--root", type=Path, default=Path("agents/pretrained/benchmark"))
    p.add_argument("--dry-run", action="store_true", help="print the commands only")
    args = p.parse_args()
    if args.jobs < 1 or args.seeds < 1 or args.robust_seeds < 1:
        p.error("--jobs, --seeds and --robust-seeds must be >= 1")
    todo = []
    for run, cmd in jobs(args.groups, args.scenes, args.seeds, args.robust_seeds, args.root):
        if (run / "model.zip").exists():
            continue
        todo.append((run, cmd))
    print(f"{len(todo)} runs to do")
    if args.dry_run:
        for _, cmd in todo:
            print(" ".join(cmd[1:]))
        return
    logs = args.root / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    running: list[tuple[subprocess.Popen, Path, float]] = []
    while todo or running:
        while todo and len(running) < args.jobs:
            run, cmd = todo.pop(0)
            if run.exists():
                shutil.rmtree(run)  # a run cut off: start it again
            with open(logs / f"{run.name}.log", "w") as log:
                proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
            running.append((proc, run, time.time()))
            print(f"started {run.name}", flush=True)
        time.sleep(POLL_S)
        for item in list(running):
            proc, run, t0 = item
            if proc.poll() is not None:
                running.remove(item)
                print(f"{run.name}: exit {proc.returncode} after {time.time() - t0:.0f} s",
                      flush=True)


if __name__ == "__main__":
    main()
