"""Train every policy of the control benchmark (``fricenv_agents.benchmark``), a few at a time.

    python scripts/train_control_benchmark.py [--jobs 2] [--seeds 5] [--rand-seeds 5]
        [--algos ppo sac ppo_rand] [--scenes paper self_excited stribeck viscous]
        [--root runs/control] [--dry-run]

Each run is ``python -m fricenv_agents.train`` with the hyperparameter file's entry for its
scene, into ``<root>/<group>_<scene>_s<seed>`` (groups: ``ppo``, ``sac``, and
``ppo_rand``, PPO trained with ``randomize=True`` for the generalisation study). A run
whose folder holds a model is skipped; a folder without one (a run cut off) is removed
and the run started again, so the command can simply be repeated until all are done.
Logs go to ``<root>/logs``. Runs use one torch thread each (``--threads 1``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

SCENES = ("paper", "self_excited", "stribeck", "viscous")
#: Group -> (algorithm, extra training arguments).
GROUPS = {
    "ppo": ("ppo", []),
    "ppo_rand": ("ppo", ["-params", "env_kwargs:{randomize: true}"]),
    "sac": ("sac", []),
}
POLL_S = 5.0


def jobs(groups: list[str], scenes: list[str], seeds: int, rand_seeds: int,
         root: Path) -> list[tuple[Path, list[str]]]:
    """(run folder, command) of every run, groups in the order given, then seeds."""
    out = []
    for group in groups:
        algo, extra = GROUPS[group]
        n = rand_seeds if group == "ppo_rand" else seeds
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
    p.add_argument("--seeds", type=int, default=5, help="training seeds of ppo and sac")
    p.add_argument("--rand-seeds", type=int, default=5, help="training seeds of ppo_rand")
    p.add_argument("--algos", nargs="+", choices=sorted(GROUPS), default=list(GROUPS))
    p.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    p.add_argument("--root", type=Path, default=Path("runs/control"))
    p.add_argument("--dry-run", action="store_true", help="print the commands only")
    args = p.parse_args()
    if args.jobs < 1 or args.seeds < 1 or args.rand_seeds < 1:
        p.error("--jobs, --seeds and --rand-seeds must be >= 1")
    todo = []
    for run, cmd in jobs(args.algos, args.scenes, args.seeds, args.rand_seeds, args.root):
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
