"""The control benchmark: every controller on every scene, and how policies generalise.

    python -m fricenv_agents.benchmark [--runs agents/pretrained/benchmark]
        [--out out/control-benchmark] [--seeds 10] [--episodes 5]
        [--scenes paper self_excited stribeck viscous] [--jobs 2]

Rows are controllers, columns scenes. The rows are data: ``ROWS`` lists each controller
once (key, label, how to build its entry, the conditions it runs in), so adding one is one
``Row`` (docs/adding_a_controller.md). Today: zero excitation, random actions, the best
constant, the feedback rule, the exact-model MPC, the MPC behind a particle filter (under
noise and delay), PPO, PPO with robust training, SAC.
Every controller faces the same held-out episodes (``fricenv_agents.evaluate``'s seed
layout: evaluation seed k < ``--seeds``, episodes j < ``--episodes``); a trained row runs
every model of its group (``<runs>/<key>_<scene>_s<seed>``, one per training seed, made by
``scripts/train_control_benchmark.py``) on every episode. A group without runs leaves its
rows out.

Generalisation: the rows that run in the study's conditions (zero excitation as the
reference, the MPC, PPO and the robustly trained PPO) are evaluated on plants drawn from
the training ranges (``in range``), from boxes of ``lambda`` and ``x_fs`` beyond both ends
of them (``held out below``, ``held out above``; the other parameters in their ranges), and
with observation noise plus a one-interval delay (``noise + delay``, plants in range).
Each condition's stick cut is ``1 - stick(controller) / stick(zero excitation)`` on the
same episodes; retention is a condition's cut over the in-range one (for the filtered MPC,
over the bound MPC's). The MPC is bound to the exact state (so the held-out boxes do not
apply to it), except under noise, where it plans from the noisy, delayed observation; the
filtered MPC plans from its particle filter's estimate instead.

Statistics (``fricenv_agents.statistics``): each cell is the interquartile mean over all
models and episodes with a 95 % bootstrap interval (training seeds, then episodes in
blocks of plant seeds); gaps, cuts and retentions
are paired over the shared episodes. Writes ``control_benchmark.md``,
``control_benchmark.json``, ``control_benchmark_episodes.csv`` (one row per episode, with
the versions of the software that ran it), ``control_benchmark_rliable.npz`` (the returns
as the ``(runs x tasks)`` matrices rliable reads, ``benchmark_records.write_rliable``)
and three figures to ``--out`` (and the
best-constant searches' caches, as ``fricenv_agents.evaluate`` does); the page ends with
the throughput of the vector env and of PPO training (``fricenv_agents.throughput``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fricenv.checks import check_output_dir

from . import statistics as S
from .benchmark_figures import plot_generalisation, plot_profiles, plot_returns
from .benchmark_records import read_episodes, versions, write_episodes, write_rliable
from .benchmark_rows import (
    ALL_CONDITIONS,
    BENCH_SCENES,
    BOOT_SEED,
    CONDITIONS,
    CUT_AGGREGATE,
    DELAY,
    GAP,
    GAP_BAR,
    HELD_OUT,
    NOISE,
    NOMINAL,
    PRETRAINED_RUNS,
    RETENTION_BAR,
    RETENTIONS,
    ROBUST_ENV_KWARGS,
    ROBUST_NOISE_FACTOR,
    ROWS,
    SCENE_COST,
    WIDTH,
    ZERO_LABEL,
    Generalisation,
    Results,
    Row,
    Setting,
    _cut_stat,
    baseline,
    check_rows,
    condition_setting,
    evaluate_condition,
    evaluate_scene,
    exact_mpc,
    filtered_mpc,
    held_out_scene,
    per_seed,
    row_keys,
    run_group,
    short_name,
    trained,
    training_groups,
)
from .benchmark_workers import map_scenes
from .cli import HelpFormatter
from .runs import portable_path
from .scoring import Entry, _summary

#: The rows, conditions and runs live in ``benchmark_rows`` (below the page, its figures and
#: its workers); this module, the page, names them too.
__all__ = [
    "ALL_CONDITIONS", "BENCH_SCENES", "BOOT_SEED", "CONDITIONS", "CUT_AGGREGATE", "DELAY",
    "GAP", "GAP_BAR", "HELD_OUT", "NOISE", "NOMINAL", "PRETRAINED_RUNS", "RETENTIONS",
    "RETENTION_BAR", "ROBUST_ENV_KWARGS", "ROBUST_NOISE_FACTOR", "ROWS", "SCENE_COST", "WIDTH",
    "ZERO_LABEL", "Generalisation", "Results", "Row", "Setting", "baseline", "build_parser",
    "check_rows", "condition_setting", "evaluate_condition", "evaluate_scene", "exact_mpc",
    "filtered_mpc", "generalisation_summary", "held_out_scene", "main", "per_seed", "row_keys",
    "run_group", "short_name", "trained", "training_groups", "write_page",
]


# -- statistics of the tables -----------------------------------------------------------------
def _cut(entry: Entry, zero: Entry) -> S.Interval:
    """Stick cut against zero excitation on the same episodes, with its paired interval."""
    return S.paired_ci(_cut_stat, [entry.matrix("stick_fraction"), zero.matrix("stick_fraction")],
                       strata=entry.n_seeds, seed=BOOT_SEED)


def _retention(conds: dict[str, dict[str, Entry]], key: str, which: Sequence[str],
               base: str | None = None) -> S.Interval:
    """The worst of the conditions ``which``'s cuts over the in-range one of ``base``
    (default: ``key`` itself), paired over every cell (the same plant seeds)."""
    cells = []
    for cond in ("in range", *which):
        own = base if cond == "in range" and base is not None else key
        cells += [conds[cond][own].matrix("stick_fraction"),
                  conds[cond]["zero"].matrix("stick_fraction")]

    def stat(*c: Any) -> Any:
        base = _cut_stat(c[0], c[1])
        worst = _cut_stat(c[2], c[3])
        for i in range(4, len(c), 2):
            worst = np.minimum(worst, _cut_stat(c[i], c[i + 1]))
        return worst / base

    return S.paired_ci(stat, cells, strata=conds["in range"]["zero"].n_seeds, seed=BOOT_SEED)


def _gap(learned: Entry, ref: Entry) -> S.Interval:
    """(IQM return of ``ref`` − that of ``learned``) / |IQM return of ``ref``|, paired
    over the shared episodes (negative: ``learned`` does better)."""
    agg = S.cell_stat(S.iqm)

    def stat(c: Any, m: Any) -> Any:
        return (agg(m) - agg(c)) / abs(agg(m))

    return S.paired_ci(stat, [learned.matrix("ret"), ref.matrix("ret")],
                       strata=learned.n_seeds, seed=BOOT_SEED)


# -- writing ----------------------------------------------------------------------------------

def _label(results: Results, key: str) -> str:
    return next(r[key].label for r in results.values() if key in r)


def main_tables(rows: Sequence[Row], results: Results, n_seeds: int,
                episodes: int) -> list[str]:
    scenes = list(results)
    head = "| controller | " + " | ".join(f"`{s}`" for s in scenes) + " |"
    rule = "|---|" + "---:|" * len(scenes)
    lines = []
    for name, title, digits in (("ret", "Return", 2), ("stick_fraction", "Stick-time fraction",
                                                       4)):
        lines += [f"### {title} (IQM [95 % CI])", "", head, rule]
        for key in row_keys(rows, results):
            cells = [nowrap(results[s][key].interval(name).format(digits))
                     if key in results[s] else "—" for s in scenes]
            lines.append(f"| {_label(results, key)} | " + " | ".join(cells) + " |")
        lines.append("")
    best = "; ".join(f"`{s}` u0 = {r['best_constant'].info['u0']:.2f}, nu = "
                     f"{r['best_constant'].info['nu']:.2f}" for s, r in results.items()
                     if "best_constant" in r)
    lines += [f"Episodes: {n_seeds} evaluation seed{'s' if n_seeds > 1 else ''} × "
              f"{episodes} episodes (n = "
              f"{n_seeds * episodes} for a controller without training seeds), every trained "
              f"model on each of them (n = models × {n_seeds * episodes}). IQM: the mean of "
              "the middle half of all those episodes' values; 95 % CI: bootstrap (2000 "
              "replicates) resampling training seeds, then episodes within each evaluation "
              "seed's block of plant seeds, the same episodes for every model "
              "(`fricenv_agents.statistics`)." + (f" Best constants: {best}." if best
                                                       else ""), ""]
    return lines


def nowrap(cell: str) -> str:
    """A table cell with no-break spaces: ``-2.07 [-2.19, -1.95]`` stays on one line in a
    narrow column instead of breaking after the estimate."""
    return cell.replace(" ", "\u00a0")


def gap_lines(rows: Sequence[Row], results: Results) -> list[str]:
    """The learned rows' gap to the MPC per scene (nothing without an MPC or a learned row)."""
    learned = [r.key for r in rows if r.train is not None]
    body: list[str] = []
    behind: list[str] = []
    for scene, r in results.items():
        ref = r.get("mpc")
        present = [k for k in learned if k in r]
        if ref is None or not present:
            continue
        body.append(f"| `{scene}` | {ref.label} | {nowrap(ref.interval('ret').format())} | "
                    "— | — | — | — |")
        for key in present:
            e, gap = r[key], _gap(r[key], ref)
            ok = gap.estimate <= GAP_BAR
            if not ok:
                behind.append(f"{short_name(rows, key)} on `{scene}` "
                              f"({100 * gap.estimate:.0f} %)")
            body.append(f"| `{scene}` | {e.label} | {nowrap(e.interval('ret').format())} | "
                        f"{nowrap(gap.format(1, 100, ' %', signed=True))} | "
                        f"{'yes' if ok else 'no'} | "
                        f"{_over_models(e)} | {_seconds(e)} |")
    if not body:
        return []
    return ["### Learned controllers against the MPC", "",
            "| scene | controller | return, IQM [95 % CI] | gap to the MPC [95 % CI] | "
            f"within {100 * GAP_BAR:.0f} % | IQM of each training seed | training time "
            "per run |", "|---|---|---:|---:|---|---:|---:|", *body, "",
            "Gap = (IQM return of the MPC − IQM return of the controller) / |IQM return "
            "of the MPC|: negative when the controller does better; its interval is a paired "
            "bootstrap over the shared episodes. IQM of each training seed: the lowest and "
            "highest of the models' IQM returns. Training times: wall time of one run on "
            "the shared 2-core machine, one torch thread.", "",
            (f"More than {100 * GAP_BAR:.0f} % behind the MPC: " + ", ".join(behind) + "."
             if behind else f"Every learned controller is within {100 * GAP_BAR:.0f} % of "
             "the MPC's return on every scene."), ""]


def _over_models(entry: Entry) -> str:
    """Range of a trained group's per-model IQM returns."""
    per_model = S.iqm(entry.matrix("ret"), axis=1)
    lo, hi = float(np.min(per_model)), float(np.max(per_model))
    return f"{lo:.2f}" if len(entry.factories) == 1 else f"{lo:.2f} to {hi:.2f}"


def _seconds(entry: Entry) -> str:
    """A trained group's range of training wall times per run."""
    secs = entry.info.get("train_seconds") or []
    if not secs:
        return "—"
    lo, hi = min(secs), max(secs)
    return f"{lo:.0f} s" if round(lo) == round(hi) else f"{lo:.0f}–{hi:.0f} s"


def generalisation_summary(gen: Generalisation, rows: Sequence[Row] = ROWS,
                           ) -> dict[str, dict[str, dict[str, S.Interval]]]:
    """scene -> controller key -> cut per condition and the two retentions."""
    bases = {r.key: r.retention_of for r in rows if r.retention_of is not None}
    out: dict[str, dict[str, dict[str, S.Interval]]] = {}
    for scene, conds in gen.items():
        out[scene] = {}
        keys = dict.fromkeys(k for c in CONDITIONS for k in conds[c] if k != "zero")
        for key in keys:
            cell = {c: _cut(conds[c][key], conds[c]["zero"]) for c in CONDITIONS
                    if key in conds[c]}
            base = bases.get(key)
            for name, which in RETENTIONS.items():
                have = all(c in cell for c in which) and (
                    "in range" in cell if base is None else base in conds["in range"])
                if have:
                    cell[name] = _retention(conds, key, which, base)
            out[scene][key] = cell
    return out



def generalisation_lines(rows: Sequence[Row], gen: Generalisation,
                         summary: dict[str, dict[str, dict[str, S.Interval]]]) -> list[str]:
    lines = ["### Generalisation and sensors", "",
             "Stick cut against zero excitation on the same episodes, in %: 1 − mean stick "
             "fraction of the controller / that of zero excitation (the share of the stuck "
             "time removed), with a 95 % paired bootstrap CI. Held-out boxes: "
             + ", ".join(f"`{s}` {_boxes(s)}" for s in gen) + f". Noise: {NOISE}, delay "
             f"{DELAY} interval.", "",
             "| scene | controller | " + " | ".join(CONDITIONS) + " |",
             "|---|---|" + "---:|" * len(CONDITIONS)]
    ret = ["", "Retention, in %: a condition's stick cut over the in-range one (held out: "
           "the worse of the two boxes), with a 95 % paired bootstrap CI.", "",
           "| scene | controller | retention, held out (worst side) | retention, noise + "
           "delay |", "|---|---|---:|---:|"]
    low = []
    for scene, per_key in summary.items():
        for key, cell in per_key.items():
            label = next(es[key].label for es in gen[scene].values() if key in es)
            lines.append(f"| `{scene}` | {label} | " + " | ".join(
                nowrap(cell[c].format(1, 100)) if c in cell else "—" for c in CONDITIONS) + " |")
            kept = {name: cell.get(name) for name in RETENTIONS}
            ret.append(f"| `{scene}` | {label} | " + " | ".join(
                nowrap(v.format(0, 100)) if v else "—" for v in kept.values()) + " |")
            low += [f"{short_name(rows, key)} on `{scene}` {name.split(', ')[1]} "
                    f"({100 * v.estimate:.0f} %)" for name, v in kept.items()
                    if v and v.estimate < RETENTION_BAR]
    return lines + ret + ["", (f"Less than {100 * RETENTION_BAR:.0f} % of the in-range cut "
                               "kept: " + "; ".join(low) + "." if low else
                               f"Every controller keeps at least {100 * RETENTION_BAR:.0f} % "
                               "of its in-range cut in every condition and scene."), ""]


def _boxes(scene: str) -> str:
    lo, hi = held_out_scene(scene, "below").ranges, held_out_scene(scene, "above").ranges
    return "; ".join(f"{k} in [{lo[k][0]:.3g}, {lo[k][1]:.3g}] or [{hi[k][0]:.3g}, "
                     f"{hi[k][1]:.3g}]" for k in HELD_OUT)


def to_json(results: Results, gen: Generalisation, summary: dict, meta: dict) -> dict:
    def iv(i: S.Interval) -> dict[str, float]:
        return {"estimate": i.estimate, "lo": i.lo, "hi": i.hi}

    def pack(e: Entry) -> dict:
        info = dict(e.info)
        if "paths" in info:  # (relative to the repository: no machine's folders)
            info["paths"] = [portable_path(Path(p)) for p in info["paths"]]
        return {**_summary(e), "iqm_ci": {f: iv(e.interval(f)) for f in ("ret",
                                                                          "stick_fraction")},
                "info": info, "per_episode": e.scores.as_dict()}

    gaps = {s: {k: iv(_gap(e, r["mpc"])) for k, e in r.items() if e.kind == "trained"}
            for s, r in results.items() if "mpc" in r}
    return {**meta,
            "scenes": {s: {k: pack(e) for k, e in r.items()} for s, r in results.items()},
            "gap_to_mpc": gaps,
            "generalisation": {s: {c: {k: pack(e) for k, e in es.items()}
                                   for c, es in conds.items()} for s, conds in gen.items()},
            "cuts_and_retentions": {s: {k: {c: iv(v) for c, v in cell.items()}
                                        for k, cell in per.items()}
                                    for s, per in summary.items()}}


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m fricenv_agents.benchmark",
                                description=__doc__.split("\n\n")[0],
                                formatter_class=HelpFormatter)
    p.add_argument("--runs", type=Path, default=PRETRAINED_RUNS,
                   help="folder of the run folders (default: the shipped ones; "
                   "scripts/train_control_benchmark.py makes them)")
    p.add_argument("--out", type=Path, default=Path("out/control-benchmark"),
                   help="output folder (the published page: --out docs/results)")
    p.add_argument("--scenes", nargs="+", choices=BENCH_SCENES, default=list(BENCH_SCENES))
    p.add_argument("--seeds", type=int, default=10, help="evaluation seeds")
    p.add_argument("--episodes", type=int, default=5, help="episodes per evaluation seed")
    p.add_argument("--grid", type=int, default=21, help="best-constant search grid")
    p.add_argument("--search-episodes", type=int, default=16,
                   help="best-constant search: episodes per candidate")
    p.add_argument("--no-generalisation", action="store_true", help="main table only")
    p.add_argument("--jobs", type=int, default=1,
                   help="scenes evaluated at a time, each in its own process")
    p.add_argument("--no-throughput", action="store_true",
                   help="leave out the throughput section (fricenv_agents.throughput)")
    p.add_argument("--max-steps", type=int, default=None,
                   help="episode length for a quick look (default: each scene's horizon)")
    return p


def main(argv: Sequence[str] | None = None, rows: Sequence[Row] = ROWS) -> Path:
    """Run the benchmark; ``rows``: the controllers (default ``ROWS``)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.episodes < 2 or args.grid < 2 or args.jobs < 1:
        parser.error("need --seeds >= 1, --episodes >= 2, --grid >= 2 and --jobs >= 1")
    if args.max_steps is not None and args.max_steps < 1:
        parser.error("--max-steps must be >= 1")
    check_rows(rows)
    base = {} if args.max_steps is None else {"max_episode_steps": args.max_steps}
    try:
        check_output_dir("--out", args.out)
    except ValueError as e:
        parser.error(str(e))
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.runs.is_dir():
        print(f"fricenv_agents.benchmark: no run folders in {args.runs}: the trained rows "
              "are left out", file=sys.stderr)
    if args.jobs > 1 and rows is not ROWS:
        parser.error("--jobs > 1 runs the registry's own rows only (ROWS)")
    t0 = time.perf_counter()
    results: Results = {}
    gen: Generalisation = {}
    for scene, (res, g) in zip(args.scenes, map_scenes(args, rows), strict=True):
        results[scene] = res
        if g:
            gen[scene] = g
    summary = generalisation_summary(gen, rows)
    throughput = None
    if not args.no_throughput:
        from . import throughput as TP

        throughput = TP.measure(args.scenes, TP.PLANTS)
    write_page(args.out, rows, results, gen, summary, args, throughput)
    meta = {"n_seeds": args.seeds, "episodes": args.episodes, "env_kwargs": base,
            "seconds": round(time.perf_counter() - t0, 1), "noise": NOISE, "delay": DELAY,
            "robust_env_kwargs": ROBUST_ENV_KWARGS, "held_out": {s: _boxes(s) for s in gen},
            "bootstrap": {"replicates": S.N_BOOT, "confidence": S.CONFIDENCE,
                          "seed": BOOT_SEED}, "versions": versions(), "jobs": args.jobs,
            "throughput": throughput}
    (args.out / "control_benchmark.json").write_text(
        json.dumps(to_json(results, gen, summary, meta), indent=1, default=str))
    runs = [(sc, NOMINAL, r) for sc, r in results.items()]
    runs += [(sc, c, es) for sc, conds in gen.items() for c, es in conds.items()]
    csv_path = args.out / "control_benchmark_episodes.csv"
    write_episodes(csv_path, runs)
    write_rliable(read_episodes(csv_path), args.out / "control_benchmark_rliable.npz")
    return args.out / "control_benchmark.md"


#: The caption of the generalisation figure on the page.
GENERALISATION_CAPTION = (
    "Stick cut against zero excitation on the same episodes, per condition of the "
    "generalisation study (in range, held-out plants below and above the training ranges, "
    "sensor noise + delay), one bar per controller: IQM with its 95 % bootstrap interval.")


def write_page(out: Path, rows: Sequence[Row], results: Results, gen: Generalisation,
               summary: dict, args: argparse.Namespace,
               throughput: dict[str, Any] | None = None) -> None:
    """``control_benchmark.md`` and its figures."""
    lines = ["# Control benchmark: controllers × scenes", "",
             "Made by `python -m fricenv_agents.benchmark` (see its docstring and "
             "[Control studies](../control.md#the-benchmark)). Raw results, one row per "
             "episode with the software versions: "
             "[control_benchmark_episodes.csv](control_benchmark_episodes.csv).", "",
             *main_tables(rows, results, args.seeds, args.episodes),
             *gap_lines(rows, results)]
    if summary:
        lines += generalisation_lines(rows, gen, summary)
    plot_returns(rows, results, out / "control_benchmark.png")
    plot_profiles(rows, results, out / "control_profiles.png")
    lines += ["![control_benchmark.png](control_benchmark.png)", "",
              "Performance profiles: the fraction of a controller's episodes (all its models) "
              "whose cost is at most τ, with 95 % bootstrap bands (Agarwal et al., NeurIPS "
              "2021).", "", "![control_profiles.png](control_profiles.png)", ""]
    if summary:
        plot_generalisation(rows, summary, out / "control_generalisation.png")
        lines += [GENERALISATION_CAPTION, "",
                  "![control_generalisation.png](control_generalisation.png)", ""]
    if throughput is not None:
        from . import throughput as TP

        lines += [*TP.markdown(throughput), ""]
    (out / "control_benchmark.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
