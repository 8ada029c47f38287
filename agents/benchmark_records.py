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


def read_episodes(path: Path) -> list[dict[str, Any]]:
    """The rows of a per-episode CSV (``write_episodes``), metrics as floats and the seed
    columns as ints. ``ValueError`` naming the file if it lacks a column."""
    import csv

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    missing = set(CSV_COLUMNS[:9]) - set(rows[0] if rows else CSV_COLUMNS)
    if not rows or missing:
        raise ValueError(f"{path}: not a per-episode benchmark CSV (missing columns "
                         f"{sorted(missing)}, {len(rows)} rows)")
    for r in rows:
        for m in METRICS:
            r[m] = float(r[m])
        for k in ("eval_seed", "episode", "plant_seed"):
            r[k] = int(r[k])
    return rows


def episode_grid(rows: list[dict[str, Any]], controller: str = "mpc") -> tuple[int, int]:
    """How many evaluation seeds and episodes per seed the nominal rows of ``controller``
    span: the grid a rerun on the benchmark's episodes must cover."""
    own = [r for r in rows if r["condition"] == "nominal" and r["controller"] == controller]
    return len({r["eval_seed"] for r in own}), len({r["episode"] for r in own})


def write_report(out: Path, stem: str, data: Any, page: str) -> Path:
    """Write ``<stem>.json`` (``data``) and ``<stem>.md`` (``page``) into ``out``, print the
    page and return its path: the ending of every report command."""
    import json

    (out / f"{stem}.json").write_text(json.dumps(data, indent=1))
    path = out / f"{stem}.md"
    path.write_text(page)
    print(page)
    return path


def cell_of(rows: list[dict[str, Any]], scene: str, condition: str, controller: str,
            metric: str = "ret") -> np.ndarray:
    """The ``(runs, episodes)`` matrix of one benchmark cell from CSV rows: one row per
    training run (sorted by name; one row without training runs), the episodes in the
    order of their plant seeds, which every run and controller shares. ``ValueError`` if
    the cell is missing or its runs did not face the same plants."""
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; expected one of {list(METRICS)}")
    mine = [r for r in rows if (r["scene"], r["condition"], r["controller"])
            == (scene, condition, controller)]
    if not mine:
        raise ValueError(f"no episodes of {controller!r} on {scene!r} ({condition})")
    runs = sorted({r["training_run"] for r in mine})
    per_run = [sorted((r for r in mine if r["training_run"] == run),
                      key=lambda r: r["plant_seed"]) for run in runs]
    seeds = [r["plant_seed"] for r in per_run[0]]
    if any([r["plant_seed"] for r in p] != seeds for p in per_run):
        raise ValueError(f"the runs of {controller!r} on {scene!r} ({condition}) did not "
                         "face the same plants")
    return np.array([[r[metric] for r in p] for p in per_run])


def rliable_scores(rows: list[dict[str, Any]], condition: str = "nominal",
                   metric: str = "ret") -> tuple[list[str], dict[str, np.ndarray]]:
    """The tasks (scenes) and, per controller present on every one of them in
    ``condition``, its ``(runs x tasks)`` score matrix in rliable's form
    (``statistics.score_matrix``: one row per training run and episode)."""
    from .statistics import score_matrix

    here = [r for r in rows if r["condition"] == condition]
    scenes = sorted({r["scene"] for r in here})
    if not scenes:
        raise ValueError(f"no episodes in condition {condition!r}")
    keys = sorted(set.intersection(*({r["controller"] for r in here if r["scene"] == s}
                                     for s in scenes)))
    return scenes, {k: score_matrix([cell_of(here, s, condition, k, metric)
                                     for s in scenes]) for k in keys}


def write_rliable(rows: list[dict[str, Any]], path: Path, metric: str = "ret") -> list[str]:
    """``path`` (``.npz``): per condition and controller on every scene, its ``(runs x
    tasks)`` matrix of ``metric`` under the key ``<condition>/<controller>``, and the
    tasks' order under ``tasks``. Returns the matrices' keys."""
    out: dict[str, np.ndarray] = {}
    tasks: list[str] | None = None
    for cond in sorted({r["condition"] for r in rows}):
        scenes, mats = rliable_scores(rows, cond, metric)
        if tasks is None:
            tasks = scenes
        if scenes != tasks:  # (a condition on fewer scenes: its own keys would mislead)
            continue
        out.update({f"{cond}/{k}": m for k, m in mats.items()})
    keys = sorted(out)
    out["tasks"] = np.array(tasks or [])
    # (numpy's stub types savez's keywords as its one flag, not as arrays)
    np.savez(path, **out)  # type: ignore[arg-type]
    return keys
