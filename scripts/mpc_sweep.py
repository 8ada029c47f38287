"""Return against compute for the MPC's settings, one at a time: the sweep behind its
generic settings (each scene's tuned ones come from ``fricenv_agents.mpc_tuning``).

    python scripts/mpc_sweep.py [--scenes stribeck self_excited] [--episodes 8]
                                [--out out/mpc-sweep]

One setting at a time is varied around the defaults (horizon, samples, iterations,
temperature, perturbation size), on tuning episodes of their own (plant seeds from
``fricenv_agents.mpc.TUNE_SEED_BASE``, never an evaluation episode), with the MPC bound to the
exact plant states. For each setting: the episodes' mean return and stick-time fraction,
and the wall time of one decision for one plant (median over rounds, numba's threads on).
Writes ``mpc_sweep.json``, ``mpc_sweep.md`` and ``mpc_sweep.png`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from fricenv_agents.mpc import (
    DEFAULT_HORIZON,
    DEFAULT_ITERATIONS,
    DEFAULT_NOISE_STD,
    DEFAULT_SAMPLES,
    DEFAULT_TEMPERATURE,
    TUNE_SEED_BASE,
    MPPIController,
)
from fricenv_agents.mpc_tuning import decisions_per_second
from fricenv_agents.rollouts import rollout

DEFAULTS = {"horizon": DEFAULT_HORIZON, "samples": DEFAULT_SAMPLES,
            "iterations": DEFAULT_ITERATIONS, "temperature": DEFAULT_TEMPERATURE,
            "noise_std": DEFAULT_NOISE_STD}
#: The values tried for each setting (the others at their defaults).
GRID: dict[str, list[Any]] = {
    "horizon": [4, 8, 12, 16, 24],
    "samples": [32, 64, 128, 256, 512],
    "iterations": [1, 2, 3],
    "temperature": [0.03, 0.1, 0.3, 1.0],
    "noise_std": [0.25, 0.5, 1.0],
}
DECISION_ROUNDS = 5
DECISIONS_PER_ROUND = 20


def decision_seconds(scene: str, settings: dict[str, Any]) -> float:
    """Median wall time of one decision for one plant, from a state 20 steps into an
    episode (the MPC's plan warm as in a run)."""
    return 1.0 / decisions_per_second(scene, settings, DECISION_ROUNDS, DECISIONS_PER_ROUND)


def configurations() -> list[tuple[str, dict[str, Any]]]:
    """(varied setting, settings) pairs, the defaults once."""
    out = [("default", dict(DEFAULTS))]
    for key, values in GRID.items():
        for v in values:
            if v != DEFAULTS[key]:
                out.append((key, {**DEFAULTS, key: v}))
    return out


def sweep(scenes: list[str], episodes: int) -> list[dict[str, Any]]:
    rows = []
    for scene in scenes:
        for varied, settings in configurations():
            t0 = time.perf_counter()
            m = rollout(MPPIController(scene, **settings), scene, TUNE_SEED_BASE, episodes)
            row = {"scene": scene, "varied": varied, **settings,
                   "return_mean": float(m.ret.mean()), "return_std": float(m.ret.std(ddof=1)),
                   "stick_fraction": float(m.stick_fraction.mean()),
                   "intervals_per_decision": (settings["samples"] * settings["horizon"]
                                              * settings["iterations"]),
                   "decision_ms": 1e3 * decision_seconds(scene, settings),
                   "run_seconds": time.perf_counter() - t0}
            rows.append(row)
            print(f"{scene:13s} {varied:11s} " + " ".join(f"{k}={settings[k]}" for k in GRID)
                  + f"  return {row['return_mean']:8.2f}  stick {row['stick_fraction']:.4f}"
                  f"  {row['decision_ms']:6.2f} ms", flush=True)
    return rows


def markdown(rows: list[dict[str, Any]], episodes: int, centre: dict[str, Any]) -> str:
    lines = [
        "# MPC settings: return against compute",
        "",
        f"MPPI bound to the exact plant states; {episodes} tuning episodes per scene and "
        "setting (plant seeds from `fricenv_agents.mpc.TUNE_SEED_BASE`, none of them an evaluation "
        "episode). One setting is varied at a time, the others at "
        + ", ".join(f"{k} = {v}" for k, v in centre.items())
        + ". Compute: plant-intervals rolled out per decision (samples x horizon x "
        "iterations), and the measured time of one decision for one plant (median of "
        f"{DECISION_ROUNDS} rounds of {DECISIONS_PER_ROUND}, numba's threads on, on the "
        "2-core machine shared with other work and with trainings running: compare the "
        "times with each other, and see scripts/bench_control.py for a decision timed "
        "side by side with the environments).",
        "",
        "| scene | varied | horizon | samples | iterations | temperature | noise_std | "
        "return | stick-time fraction | intervals per decision | ms per decision |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['varied'].replace('default', 'centre')} | {r['horizon']} | "
            f"{r['samples']} | "
            f"{r['iterations']} | {r['temperature']:g} | {r['noise_std']:g} | "
            f"{r['return_mean']:.2f} ± {r['return_std']:.2f} | {r['stick_fraction']:.4f} | "
            f"{r['intervals_per_decision']} | {r['decision_ms']:.2f} |")
    lines += ["", "The MPC's generic settings (`fricenv_agents.mpc.DEFAULT_*`, for a scene "
              "without tuned ones): " + ", ".join(f"{k} = {v}" for k, v in DEFAULTS.items())
              + ". Each benchmark scene's own defaults come from the search of "
              "[mpc_tuning.md](mpc_tuning.md).", "",
              "![mpc_sweep.png](mpc_sweep.png)", ""]
    return "\n".join(lines)


def plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = sorted({r["scene"] for r in rows})
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.6 * len(scenes), 3.6), squeeze=False)
    for ax, scene in zip(axes[0], scenes, strict=True):
        for c, key in enumerate(GRID):
            pts = [r for r in rows if r["scene"] == scene and r["varied"] in (key, "default")]
            pts.sort(key=lambda r: r[key])
            ax.plot([r["intervals_per_decision"] for r in pts],
                    [-r["return_mean"] for r in pts], "o-", color=f"C{c}", label=key, ms=3,
                    lw=1)
        d = next(r for r in rows if r["scene"] == scene and r["varied"] == "default")
        ax.plot(d["intervals_per_decision"], -d["return_mean"], "k*", ms=10, label="centre")
        ax.set_xscale("log")
        ax.set_yscale("log")  # (returns are negative: their size, lower is better)
        ax.set_xlabel("plant-intervals per decision (one plant)")
        ax.set_ylabel("episode cost = -return")
        ax.set_title(scene, fontsize=10)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenes", nargs="+", default=["stribeck", "self_excited"])
    p.add_argument("--episodes", type=int, default=8)
    p.add_argument("--out", type=Path, default=Path("out/mpc-sweep"))
    p.add_argument("--replot", type=Path, default=None,
                   help="write the table and figure from this mpc_sweep.json, running nothing")
    args = p.parse_args()
    if args.episodes < 2:
        p.error("--episodes must be >= 2")
    centre = dict(DEFAULTS)
    if args.replot is not None:
        saved = json.loads(args.replot.read_text())
        rows, args.episodes, centre = saved["rows"], saved["episodes"], saved["defaults"]
        for r in rows:
            r["intervals_per_decision"] = r["samples"] * r["horizon"] * r["iterations"]
    else:
        rows = sweep(args.scenes, args.episodes)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "mpc_sweep.json").write_text(json.dumps(
        {"defaults": centre, "grid": GRID, "episodes": args.episodes,
         "seed_base": TUNE_SEED_BASE, "rows": rows}, indent=1))
    (args.out / "mpc_sweep.md").write_text(markdown(rows, args.episodes, centre))
    plot(rows, args.out / "mpc_sweep.png")
    print(f"wrote {args.out / 'mpc_sweep.md'}")


if __name__ == "__main__":
    main()
