"""PPO against the tuned MPC on the benchmark's own episodes: the claims that must survive
the strong baseline.

    python -m fricenv_agents.mpc_compare [--scenes self_excited paper viscous stribeck]
        [--csv docs/results/control_benchmark_episodes.csv] [--out out/mpc-compare]

The benchmark's MPC rows (``control_benchmark_episodes.csv``, controller ``mpc``) were run
with the settings the MPC had then. This reruns the exact-model MPC, nominal condition,
with each scene's tuned settings (``fricenv_agents.mpc.TUNED``) on the same held-out
episodes, seeded per evaluation seed as the benchmark seeds it
(``benchmark_rows.exact_mpc``, ``scoring.run_entry``), and compares PPO's five shipped
runs with it from the shipped CSV. Per scene:

- IQM and mean return of both, each with its bootstrap interval, and the gap
  ``(MPC - PPO) / |MPC|`` by each, with its paired interval (negative: PPO ahead);
- CVaR: the mean of the worst 5 % of episodes of each;
- the share of paired episodes PPO wins (each run's episode against the MPC's on the
  same plant).

Writes ``mpc_tuned_episodes.csv`` (the rerun, in the benchmark's CSV format, controller
``mpc_tuned``) and ``mpc_compare.md`` / ``mpc_compare.json`` to ``--out``. A scene already
in ``--out``'s CSV is not run again, so the command resumes and a page can be remade
without compute. ``--generic-csv`` (default ``docs/results/mpc_generic_episodes.csv``, the
MPC's nominal episodes with its earlier generic settings) adds the same statistics against
that MPC for reference.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from . import statistics as S
from .benchmark_records import (
    METRICS,
    cell_of,
    episode_grid,
    read_episodes,
    versions,
    write_report,
)
from .cli import HelpFormatter, Stages
from .layout import check_scene, eval_env_seed

TUNED_KEY = "mpc_tuned"
GENERIC_KEY = "mpc_generic"
CSV_NAME = "mpc_tuned_episodes.csv"
RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"
DEFAULT_CSV = RESULTS / "control_benchmark_episodes.csv"
#: The MPC's nominal episodes with its earlier generic settings (the benchmark run of
#: 2026-11-27, before the search), kept for the reference table.
GENERIC_CSV = RESULTS / "mpc_generic_episodes.csv"
TAIL = 0.05  #: the share of worst episodes CVaR averages
BOOT_SEED = 0


def run_tuned(scene: str, n_seeds: int, episodes: int) -> list[dict[str, Any]]:
    """The tuned exact-model MPC on the benchmark's nominal episodes of ``scene``, as CSV
    rows (the benchmark's columns, controller ``mpc_tuned``)."""
    from .mpc import MPPIController
    from .rollouts import rollout

    out = []
    for k in range(n_seeds):
        ctrl = MPPIController(scene, {}, seed=k)
        m = rollout(ctrl, scene, eval_env_seed(k), episodes)
        for j in range(episodes):
            out.append({"scene": scene, "condition": "nominal", "controller": TUNED_KEY,
                        "label": "MPC (MPPI, exact model, tuned settings)",
                        "training_run": "", "training_seed": "", "eval_seed": k,
                        "episode": j, "plant_seed": eval_env_seed(k) + j,
                        **{f: float(getattr(m, f)[j]) for f in METRICS}})
    return out


def _gap_stat(aggregate: S.Aggregate) -> Any:
    agg = S.cell_stat(aggregate)
    return lambda c, m: (agg(m) - agg(c)) / abs(agg(m))


def compare_scene(rows: list[dict[str, Any]], scene: str, ref: str = TUNED_KEY,
                  learned: str = "ppo") -> dict[str, Any]:
    """PPO (``learned``) against the MPC (``ref``) on ``scene``'s nominal episodes: the
    statistics the module docstring lists, each an ``Interval`` as a dict."""
    c, m = (cell_of(rows, scene, "nominal", k) for k in (learned, ref))
    if c.shape[1] != m.shape[1]:
        raise ValueError(f"{learned!r} and {ref!r} on {scene!r} ran different episodes "
                         f"({c.shape[1]} and {m.shape[1]})")
    strata = len({r["eval_seed"] for r in rows if r["scene"] == scene
                  and r["controller"] == ref})

    def iv(i: S.Interval) -> dict[str, float]:
        return {"estimate": i.estimate, "lo": i.lo, "hi": i.hi}

    out: dict[str, Any] = {"n_learned": int(c.size), "n_ref": int(m.size)}
    for name, agg in (("iqm", S.iqm), ("mean", S.mean)):
        out[f"{name}_learned"] = iv(S.iqm_ci(c, strata, seed=BOOT_SEED, aggregate=agg))
        out[f"{name}_ref"] = iv(S.iqm_ci(m, strata, seed=BOOT_SEED, aggregate=agg))
        out[f"gap_{name}"] = iv(S.paired_ci(_gap_stat(agg), [c, m], strata, seed=BOOT_SEED))
    out["cvar_learned"] = float(S.cvar(c, TAIL))
    out["cvar_ref"] = float(S.cvar(m, TAIL))
    out["worst_learned"], out["worst_ref"] = float(c.min()), float(m.min())
    out["win_share"] = iv(S.paired_ci(S.win_share, [c, m], strata, seed=BOOT_SEED))
    return out


def _fmt(d: dict[str, float], digits: int = 2, scale: float = 1.0, suffix: str = "",
         signed: bool = False) -> str:
    return S.Interval(d["estimate"], d["lo"], d["hi"]).format(digits, scale, suffix, signed)


def sentence(scene: str, r: dict[str, Any], ref: str = "the tuned MPC") -> str:
    """One sentence that says where PPO leads and where it trails, together."""
    def side(gap: float) -> str:
        return "ahead of" if gap < 0 else "behind"

    def pct(gap: float) -> str:
        return f"{100 * abs(gap):.{1 if abs(gap) < 0.1 else 0}f} %"

    gi, gm = r["gap_iqm"]["estimate"], r["gap_mean"]["estimate"]
    tail = "better" if r["cvar_learned"] > r["cvar_ref"] else "worse"
    return (f"On `{scene}` PPO is {pct(gi)} {side(gi)} {ref} by the "
            f"IQM and {pct(gm)} {side(gm)} it by the mean, wins "
            f"{100 * r['win_share']['estimate']:.0f} % of paired episodes, and its worst "
            f"5 % of episodes are {tail} ({r['cvar_learned']:.2f} against "
            f"{r['cvar_ref']:.2f}).")


def markdown(results: dict[str, dict[str, Any]], old: dict[str, dict[str, Any]]) -> str:
    """The comparison page."""
    lines = [
        "# PPO against the tuned MPC",
        "",
        "Made by `python -m fricenv_agents.mpc_compare` (see its docstring). Nominal "
        "condition, the benchmark's 10 evaluation seeds × 5 episodes: PPO's five shipped "
        "runs (`agents/pretrained/benchmark/ppo_<scene>_s*`, from "
        "[control_benchmark_episodes.csv](control_benchmark_episodes.csv)) against the "
        "exact-model MPC rerun with its tuned settings ([the search](mpc_tuning.md)) on "
        "the same plants ([mpc_tuned_episodes.csv](mpc_tuned_episodes.csv)). Gap = (MPC − "
        "PPO) / |MPC|: negative when PPO does better. Intervals: 95 %, 2000 bootstrap "
        "replicates over training runs and, within each evaluation seed's block of plant "
        "seeds, episodes; the gaps and the win share paired over the shared episodes. "
        "CVaR 5 %: the mean return of the worst 5 % of episodes (PPO: 13 of 250, the MPC: "
        "3 of 50). Win share: PPO's runs' episodes that return more than the MPC's on "
        "the same plant (ties half).",
        "",
        "| scene | PPO, IQM | tuned MPC, IQM | gap by IQM | PPO, mean | tuned MPC, mean | "
        "gap by mean | CVaR 5 %, PPO / MPC | worst episode, PPO / MPC | PPO wins |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for scene, r in results.items():
        lines.append(
            f"| `{scene}` | {_fmt(r['iqm_learned'])} | {_fmt(r['iqm_ref'])} | "
            f"{_fmt(r['gap_iqm'], 1, 100, ' %', True)} | {_fmt(r['mean_learned'])} | "
            f"{_fmt(r['mean_ref'])} | {_fmt(r['gap_mean'], 1, 100, ' %', True)} | "
            f"{r['cvar_learned']:.2f} / {r['cvar_ref']:.2f} | "
            f"{r['worst_learned']:.2f} / {r['worst_ref']:.2f} | "
            f"{_fmt(r['win_share'], 0, 100, ' %')} |")
    lines += ["", *(sentence(s, r) for s, r in results.items()), ""]
    if old:
        lines += ["For reference, the same statistics against the MPC with its earlier "
                  "generic settings (horizon 12, 256 samples, 2 iterations, temperature "
                  "0.1; the benchmark run of 2026-11-27, [its episodes]"
                  "(mpc_generic_episodes.csv)):", "",
                  "| scene | that MPC, IQM | gap by IQM | that MPC, mean | gap by mean | "
                  "PPO wins |", "|---|---:|---:|---:|---:|---:|"]
        for scene, r in old.items():
            lines.append(f"| `{scene}` | {_fmt(r['iqm_ref'])} | "
                         f"{_fmt(r['gap_iqm'], 1, 100, ' %', True)} | {_fmt(r['mean_ref'])} | "
                         f"{_fmt(r['gap_mean'], 1, 100, ' %', True)} | "
                         f"{_fmt(r['win_share'], 0, 100, ' %')} |")
        lines.append("")
    return "\n".join(lines)


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    import csv

    from .benchmark_records import CSV_COLUMNS

    tags = {f"{d}_version": v for d, v in versions().items()}
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({**r, **{k: r.get(k, v) for k, v in tags.items()}})


def main(argv: Sequence[str] | None = None) -> Path:
    p = argparse.ArgumentParser(prog="python -m fricenv_agents.mpc_compare",
                                description=__doc__.split("\n\n")[0],
                                formatter_class=HelpFormatter)
    p.add_argument("--scenes", nargs="+", default=["self_excited", "paper", "viscous",
                                                   "stribeck"])
    p.add_argument("--csv", type=Path, default=DEFAULT_CSV,
                   help="the benchmark's per-episode CSV (PPO's and the earlier MPC's rows)")
    p.add_argument("--generic-csv", type=Path, default=GENERIC_CSV,
                   help="the MPC's episodes with its earlier generic settings, for the "
                        "reference table (left out if the file does not exist)")
    p.add_argument("--out", type=Path, default=Path("out/mpc-compare"))
    args = p.parse_args(argv)
    for s in args.scenes:
        check_scene(s)
    bench = read_episodes(args.csv)
    n_seeds, episodes = episode_grid(bench)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / CSV_NAME
    tuned = read_episodes(path) if path.exists() else []
    say = Stages("mpc_compare")
    for scene in args.scenes:
        if any(r["scene"] == scene for r in tuned):
            continue
        say(f"{scene}: the tuned MPC on {n_seeds} x {episodes} episodes")
        tuned += run_tuned(scene, n_seeds, episodes)
        _write_csv(path, tuned)
    done = [s for s in args.scenes if any(r["scene"] == s for r in tuned)]
    generic = ([dict(r, controller=GENERIC_KEY) for r in read_episodes(args.generic_csv)]
               if args.generic_csv.exists() else [])
    rows = bench + tuned + generic
    results = {s: compare_scene(rows, s) for s in done}
    old = {s: compare_scene(rows, s, ref=GENERIC_KEY) for s in done
           if any(r["scene"] == s for r in generic)}
    return write_report(args.out, "mpc_compare",
                        {"tail": TAIL, "bootstrap": {"replicates": S.N_BOOT, "seed": BOOT_SEED},
                         "tuned": results, "earlier_settings": old}, markdown(results, old))


if __name__ == "__main__":
    main()
