"""The control benchmark's raw results: one CSV row per episode, with the versions of the
software that made it. Independent of the benchmark's rows, so that any table of scored
entries can be written the same way.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from .scoring import Entry

#: Distributions whose versions every result records (``python``: the interpreter).
VERSIONED = ("fricenv", "numpy", "numba", "torch", "stable_baselines3")
METRICS = ("stick_fraction", "rms_vr", "rms_vr_fluct", "effort", "ret", "length")
CSV_COLUMNS = ("scene", "condition", "controller", "label", "training_run", "training_seed",
               "eval_seed", "episode", "plant_seed", *METRICS,
               *(f"{d}_version" for d in (*VERSIONED, "python")))


def versions() -> dict[str, str]:
    """Installed versions of the software that makes the numbers (read when called)."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in VERSIONED:
        try:
            out[dist] = version(dist.replace("_", "-"))
        except PackageNotFoundError:
            out[dist] = "not installed"
    out["python"] = platform.python_version()
    return out


def episode_rows(scene: str, condition: str, e: Entry) -> list[dict[str, Any]]:
    """One dict per episode of ``e``: which model, evaluation seed, episode and plant seed,
    and every metric (the order of ``run_entry``: models, then seeds, then episodes)."""
    from .layout import eval_env_seed

    runs = [Path(p).name for p in e.info.get("paths", [])] or [""] * len(e.factories)
    seeds = e.info.get("seeds") or [""] * len(e.factories)
    values = {m: np.asarray(getattr(e.scores, m)) for m in METRICS}
    out, i = [], 0
    for run, seed in zip(runs, seeds, strict=True):
        for k in range(e.n_seeds):
            for j in range(e.episodes):
                out.append({"scene": scene, "condition": condition, "controller": e.key,
                            "label": e.label, "training_run": run, "training_seed": seed,
                            "eval_seed": k, "episode": j, "plant_seed": eval_env_seed(k) + j,
                            **{m: values[m][i].item() for m in METRICS}})
                i += 1
    return out


def write_episodes(path: Path,
                   runs: Iterable[tuple[str, str, dict[str, Entry]]]) -> int:
    """The per-episode CSV of ``runs`` (scene, condition, key -> scored entry); returns its
    number of rows."""
    import csv

    tags = {f"{d}_version": v for d, v in versions().items()}
    n = 0
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for scene, cond, entries in runs:
            for e in entries.values():
                for row in episode_rows(scene, cond, e):
                    w.writerow({**row, **tags})
                    n += 1
    return n
