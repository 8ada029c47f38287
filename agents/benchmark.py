"""The control benchmark: every controller on every scene, and how policies generalise.

    python -m fricenv_agents.benchmark --runs runs/control --out docs/results [--seeds 5]
        [--episodes 10] [--scenes paper self_excited stribeck viscous]

Rows are controllers (zero excitation, random actions, best constant, the feedback rule,
the exact-model MPC, PPO, SAC), columns scenes. Every controller faces the same held-out
episodes (``fricenv_agents.evaluate``'s seed layout: evaluation seed k < ``--seeds``, episodes
j < ``--episodes``); a group of trained runs (``<runs>/ppo_<scene>_s<seed>``,
``<runs>/sac_<scene>_s<seed>``, one per training seed, made by
``scripts/train_control_benchmark.py``) runs every model on every episode.

Generalisation: the PPO policies trained with ``randomize=True``
(``<runs>/ppo_rand_<scene>_s<seed>``) are evaluated on plants drawn from the training
ranges (``in range``), from boxes of ``lambda`` and ``x_fs`` beyond both ends of them
(``held out below``, ``held out above``; the other parameters in their ranges), and with
observation noise plus a one-step delay (``noise + delay``, plants in range). Each
condition's stick cut is ``1 - stick(policy) / stick(zero excitation)`` on the same
episodes; retention is a condition's cut over the in-range one. The nominally trained
PPO and the MPC (bound to the exact state, or under noise planning from the noisy,
delayed observation) are shown beside it.

Writes ``control_benchmark.md``, ``control_benchmark.json`` and two figures to ``--out``
(and the best-constant searches' caches, as ``fricenv_agents.evaluate`` does).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fricenv.checks import check_output_dir
from fricenv.envs.scenes import SCENES, Scene

from .cli import HelpFormatter
from .layout import BASELINES, check_disjoint
from .mpc import MPPIController
from .rollouts import fmt_pm, summarize
from .scoring import (
    Entry,
    _summary,
    baseline_entries,
    load_models,
    run_entry,
    trained_entries,
)

BENCH_SCENES = ("paper", "self_excited", "stribeck", "viscous")
ROW_ORDER = (*BASELINES, "mpc", "ppo", "sac")
#: Parameters whose ranges the held-out plants leave, and by how much: a box from
#: ``GAP`` to ``GAP + WIDTH`` range widths beyond each end (lambda floored at 0).
HELD_OUT = ("lam", "xfs")
GAP, WIDTH = 0.1, 0.5
#: Sensor noise of the ``noise + delay`` condition (standard deviation per channel).
NOISE = {"x": 0.05, "v_rel": 0.05, "cos1": 0.02, "sin1": 0.02, "cos2": 0.02, "sin2": 0.02}
DELAY = 1
CONDITIONS = ("in range", "held out below", "held out above", "noise + delay")
#: The tables flag PPO more than this fraction of |MPC return| behind the MPC, and a
#: randomised policy keeping less than ``RETENTION_BAR`` of its in-range stick cut.
GAP_BAR = 0.05
RETENTION_BAR = 0.8


def held_out_scene(scene: str, side: str) -> Scene:
    """``scene`` with its ranges of ``HELD_OUT`` moved beyond their ``side`` ("below" or
    "above") end; the other randomised parameters keep their ranges."""
    sc = SCENES[scene]
    ranges = sc.ranges
    for key in HELD_OUT:
        lo, hi = ranges[key]
        w = hi - lo
        if side == "below":
            ranges[key] = (max(0.0, lo - (GAP + WIDTH) * w), lo - GAP * w)
        else:
            ranges[key] = (hi + GAP * w, hi + (GAP + WIDTH) * w)
    return sc.replace(name=f"{scene}_held_out_{side}", randomization=ranges)


def run_group(root: Path, group: str, scene: str) -> list[Path]:
    """Finished run folders of ``group`` (ppo, sac, ppo_rand) for ``scene``."""
    return sorted(p for p in root.glob(f"{group}_{scene}_s*") if (p / "model.zip").exists())


def _mpc_entry(scene: str | Scene, env_kwargs: dict, bound: bool = True) -> Entry:
    def factory(k: int) -> MPPIController:
        return MPPIController(scene, env_kwargs, seed=k, exact_state=bound)

    ctrl = factory(0)
    return Entry("mpc", ctrl.label, "baseline", [factory], ctrl.describe())


def _trained(root: Path, group: str, scene: str, n_seeds: int, episodes: int,
             key: str) -> list[Entry]:
    paths = run_group(root, group, scene)
    if not paths:
        return []
    loaded = load_models(paths)
    for p, (_, cfg) in loaded.items():
        check_disjoint(cfg, n_seeds, episodes, str(p))
    entries, _ = trained_entries(paths, scene, loaded)
    for e in entries:
        e.key = key
    return entries


def evaluate_scene(scene: str, root: Path, out: Path, n_seeds: int, episodes: int,
                   search: dict[str, Any], base: dict[str, Any]) -> dict[str, Entry]:
    """Every controller of the main table on ``scene``'s nominal episodes (``base``: env
    kwargs of every run, e.g. a shorter ``max_episode_steps``)."""
    entries = baseline_entries(list(BASELINES), scene, base, out, search)
    entries.append(_mpc_entry(scene, base))
    entries += _trained(root, "ppo", scene, n_seeds, episodes, "ppo")
    entries += _trained(root, "sac", scene, n_seeds, episodes, "sac")
    for e in entries:
        t = time.perf_counter()
        run_entry(e, scene, base, n_seeds, episodes)
        e.info["eval_seconds"] = round(time.perf_counter() - t, 2)
        print(f"  {scene:13s} {e.label[:40]:40s} return {e.scores.ret.mean():9.2f}  "
              f"stick {e.scores.stick_fraction.mean():.4f}", flush=True)
    return {e.key: e for e in entries}


def evaluate_generalisation(scene: str, root: Path, n_seeds: int, episodes: int,
                            base: dict[str, Any]) -> dict[str, dict[str, Entry]]:
    """Condition -> controller key -> entry, for the randomised PPO and its references."""
    rand = _trained(root, "ppo_rand", scene, n_seeds, episodes, "ppo_rand")
    nominal = _trained(root, "ppo", scene, n_seeds, episodes, "ppo")
    result: dict[str, dict[str, Entry]] = {}
    for cond in CONDITIONS:
        kw: dict[str, Any] = {**base, "randomize": True}
        sc: str | Scene = scene
        if cond.startswith("held out"):
            sc = held_out_scene(scene, cond.split()[-1])
        if cond == "noise + delay":
            kw.update(obs_noise=NOISE, obs_delay=DELAY)
        zero = baseline_entries(["zero"], scene, kw, Path("."), {})[0]
        entries = [zero, _mpc_entry(sc, kw, bound=cond != "noise + delay")]
        entries += _fresh(rand) + _fresh(nominal)
        for e in entries:
            run_entry(e, sc, kw, n_seeds, episodes)
        result[cond] = {e.key: e for e in entries}
        cuts = {k: _cut(e, zero) for k, e in result[cond].items() if k != "zero"}
        print(f"  {scene:13s} {cond:15s} stick cut " +
              ", ".join(f"{k} {100 * c:.1f} %" for k, c in cuts.items()), flush=True)
    return result


def _fresh(entries: list[Entry]) -> list[Entry]:
    """Copies of trained entries without their metrics (one per condition)."""
    return [Entry(e.key, e.label, e.kind, e.factories, dict(e.info)) for e in entries]


def _cut(entry: Entry, zero: Entry) -> float:
    z = float(zero.scores.stick_fraction.mean())
    return 1.0 - float(entry.scores.stick_fraction.mean()) / z if z > 0 else float("nan")


# -- writing ----------------------------------------------------------------------------------
def _cell(e: Entry | None, field: str, digits: int) -> str:
    if e is None or e.metrics is None:
        return "—"
    return fmt_pm(*summarize(getattr(e.metrics, field)), digits=digits)


def _label(results: dict[str, dict[str, Entry]], key: str) -> str:
    if key == "zero":  # (the paper scene's actions drive nu only: its u0 stays 2)
        return "zero excitation (paper: no control, u0 = 2 and nu = 0.1 held)"
    for entries in results.values():
        if key in entries:
            lab = entries[key].label
            return lab if key != "best_constant" else "best constant"
    return key


def main_tables(results: dict[str, dict[str, Entry]], n_seeds: int, episodes: int) -> list[str]:
    scenes = list(results)
    head = "| controller | " + " | ".join(f"`{s}`" for s in scenes) + " |"
    rule = "|---|" + "---:|" * len(scenes)
    lines = []
    for field, title, digits in (("ret", "Return", 2), ("stick_fraction", "Stick-time fraction",
                                                        4)):
        lines += [f"### {title} (mean ± sd over episodes)", "", head, rule]
        for key in ROW_ORDER:
            if not any(key in r for r in results.values()):
                continue
            cells = [_cell(results[s].get(key), field, digits) for s in scenes]
            lines.append(f"| {_label(results, key)} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["Episodes: " + f"{n_seeds} evaluation seeds × {episodes} episodes per "
              f"controller (n = {n_seeds * episodes} for a baseline), every trained model on "
              f"each of them (n = models × {n_seeds * episodes}); sd over all those episodes. "
              "Best constants: " + "; ".join(
                  f"`{s}` u0 = {r['best_constant'].info['u0']:.2f}, nu = "
                  f"{r['best_constant'].info['nu']:.2f}" for s, r in results.items()
                  if "best_constant" in r) + ".", ""]
    return lines


def gap_lines(results: dict[str, dict[str, Entry]]) -> list[str]:
    lines = ["### PPO against the MPC", "",
             "| scene | MPC return | PPO return | PPO over training seeds | PPO / MPC gap | "
             f"within {100 * GAP_BAR:.0f} % | PPO training time per run | SAC return | "
             "SAC over training seeds | SAC training time per run |",
             "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|"]
    behind = []
    for scene, r in results.items():
        mpc, ppo, sac = r.get("mpc"), r.get("ppo"), r.get("sac")
        if mpc is None or ppo is None:
            continue
        m, p = float(mpc.scores.ret.mean()), float(ppo.scores.ret.mean())
        gap = (m - p) / abs(m)
        if gap > GAP_BAR:
            behind.append(f"`{scene}` ({100 * gap:.0f} %)")
        s_ret = f"{sac.scores.ret.mean():.2f}" if sac else "—"
        lines.append(f"| `{scene}` | {m:.2f} | {p:.2f} | {_over_models(ppo)} | "
                     f"{100 * gap:+.1f} % | {'yes' if gap <= GAP_BAR else 'no'} | "
                     f"{_seconds(ppo)} | {s_ret} | {_over_models(sac)} | {_seconds(sac)} |")
    lines += ["", "Gap = (MPC return − PPO return) / |MPC return|: negative when PPO does "
              "better. Over training seeds: mean ± sd of the training seeds' mean returns "
              "(each over all the held-out episodes). Training times: wall time of one run "
              "on the shared 2-core machine, one torch thread.", "",
              (f"PPO is more than {100 * GAP_BAR:.0f} % behind the MPC on "
               + ", ".join(behind) + "." if behind else
               f"PPO is within {100 * GAP_BAR:.0f} % of the MPC's return on every scene."),
              ""]
    return lines


def _over_models(entry: Entry | None) -> str:
    """Mean ± sd over a trained group's models of each model's mean return."""
    if entry is None or entry.metrics is None:
        return "—"
    per_model = entry.metrics.ret.reshape(len(entry.factories), -1).mean(axis=1)
    return fmt_pm(*summarize(per_model), digits=2)


def _seconds(entry: Entry | None) -> str:
    """A trained group's range of training wall times per run."""
    secs = [] if entry is None else entry.info.get("train_seconds") or []
    if not secs:
        return "—"
    lo, hi = min(secs), max(secs)
    return f"{lo:.0f} s" if round(lo) == round(hi) else f"{lo:.0f}–{hi:.0f} s"


def generalisation_lines(gen: dict[str, dict[str, dict[str, Entry]]]) -> list[str]:
    lines = ["### Generalisation of PPO trained with `randomize=True`", "",
             "Stick cut against zero excitation on the same episodes (retention: over the "
             "in-range cut). Held-out boxes: "
             + ", ".join(f"`{s}` {_boxes(s)}" for s in gen) + f". Noise: {NOISE}, delay "
             f"{DELAY} interval.", "",
             "| scene | controller | " + " | ".join(CONDITIONS)
             + " | retention, held out (worst side) | retention, noise + delay |",
             "|---|---|" + "---:|" * (len(CONDITIONS) + 2)]
    low = []
    for scene, conds in gen.items():
        keys = [k for k in conds[CONDITIONS[0]] if k != "zero"]
        for key in keys:
            cuts = dict(zip(CONDITIONS, (_cut(conds[c][key], conds[c]["zero"])
                                         for c in CONDITIONS), strict=True))
            base = cuts["in range"]
            held = min(cuts["held out below"], cuts["held out above"]) / base
            noisy = cuts["noise + delay"] / base
            label = conds[CONDITIONS[0]][key].label
            if key == "ppo_rand":
                label = "PPO, randomised training " + label[label.find("("):]
                low += [f"`{scene}` {what} ({100 * v:.0f} %)" for what, v in
                        (("held out", held), ("noise + delay", noisy)) if v < RETENTION_BAR]
            lines.append(f"| `{scene}` | {label} | " + " | ".join(
                f"{100 * c:.1f} %" for c in cuts.values())
                + f" | {100 * held:.0f} % | {100 * noisy:.0f} % |")
    lines += ["", "Retention: a condition's stick cut over the in-range one (held out: the "
              "worse of the two boxes).", "",
              (f"The randomised PPO keeps less than {100 * RETENTION_BAR:.0f} % of its "
               "in-range cut on " + ", ".join(low) + "." if low else
               f"The randomised PPO keeps at least {100 * RETENTION_BAR:.0f} % of its "
               "in-range cut in every condition and scene."), ""]
    return lines


def _boxes(scene: str) -> str:
    lo, hi = held_out_scene(scene, "below").ranges, held_out_scene(scene, "above").ranges
    return "; ".join(f"{k} in [{lo[k][0]:.3g}, {lo[k][1]:.3g}] or [{hi[k][0]:.3g}, "
                     f"{hi[k][1]:.3g}]" for k in HELD_OUT)


SHORT = {"zero": "zero", "random": "random", "best_constant": "best constant",
         "feedback": "feedback rule", "mpc": "MPC", "ppo": "PPO", "sac": "SAC"}


def plot_returns(results: dict[str, dict[str, Entry]], path: Path) -> None:
    """Each scene's episode cost (-return) per controller, on a log axis: the learned and
    model-based controllers lie one to two orders of magnitude below the baselines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(results)
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.4 * len(scenes), 3.2), squeeze=False,
                             sharey=True)
    keys = [k for k in ROW_ORDER if any(k in r for r in results.values())]
    for ax, scene in zip(axes[0], scenes, strict=True):
        for y, key in enumerate(keys):
            e = results[scene].get(key)
            if e is None:
                continue
            cost = -e.scores.ret
            mean, sd = float(cost.mean()), float(cost.std(ddof=1))
            lo = min(sd, 0.9 * mean)  # (a log axis has no room below zero)
            ax.errorbar(mean, y, xerr=[[lo], [sd]], fmt="o", color=f"C{y}", ms=5, capsize=2)
        ax.set_xscale("log")
        ax.set_yticks(range(len(keys)), [SHORT.get(k, k) for k in keys], fontsize=8)
        ax.grid(axis="x", alpha=0.3)
        ax.set_title(scene, fontsize=10)
        ax.set_xlabel("episode cost = -return (lower is better)", fontsize=8)
    axes[0][0].invert_yaxis()  # (shared: once for all) the table's order, top down
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


GEN_SHORT = {"mpc": "MPC", "ppo_rand": "PPO, randomised training",
             "ppo": "PPO, nominal training"}


def plot_generalisation(gen: dict[str, dict[str, dict[str, Entry]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(gen)
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.6 * len(scenes), 3.2), squeeze=False)
    for ax, scene in zip(axes[0], scenes, strict=True):
        conds = gen[scene]
        keys = [k for k in conds[CONDITIONS[0]] if k != "zero"]
        width = 0.8 / max(1, len(keys))
        for j, key in enumerate(keys):
            cuts = [100 * _cut(conds[c][key], conds[c]["zero"]) for c in CONDITIONS]
            ax.bar(np.arange(len(CONDITIONS)) + j * width, cuts, width,
                   label=GEN_SHORT.get(key, key))
        ax.set_xticks(np.arange(len(CONDITIONS)) + 0.4 - width / 2,
                      [c.replace(" ", "\n", 1) for c in CONDITIONS], fontsize=7)
        ax.set_ylim(min(0.0, ax.get_ylim()[0]), 105)
        ax.set_ylabel("stick cut vs zero excitation (%)", fontsize=8)
        ax.set_title(scene, fontsize=10)
    axes[0][0].legend(fontsize=6, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def to_json(results: dict, gen: dict, meta: dict) -> dict:
    def pack(e: Entry) -> dict:
        return {**_summary(e), "info": e.info, "per_episode": e.scores.as_dict()}

    return {**meta,
            "scenes": {s: {k: pack(e) for k, e in r.items()} for s, r in results.items()},
            "generalisation": {s: {c: {k: pack(e) for k, e in es.items()}
                                   for c, es in conds.items()} for s, conds in gen.items()}}


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m fricenv_agents.benchmark",
                                description=__doc__.split("\n\n")[0],
                                formatter_class=HelpFormatter)
    p.add_argument("--runs", type=Path, default=Path("runs/control"),
                   help="folder of the run folders (scripts/train_control_benchmark.py)")
    p.add_argument("--out", type=Path, default=Path("docs/results"), help="output folder")
    p.add_argument("--scenes", nargs="+", choices=BENCH_SCENES, default=list(BENCH_SCENES))
    p.add_argument("--seeds", type=int, default=5, help="evaluation seeds")
    p.add_argument("--episodes", type=int, default=10, help="episodes per evaluation seed")
    p.add_argument("--grid", type=int, default=21, help="best-constant search grid")
    p.add_argument("--search-episodes", type=int, default=16,
                   help="best-constant search: episodes per candidate")
    p.add_argument("--no-generalisation", action="store_true", help="main table only")
    p.add_argument("--max-steps", type=int, default=None,
                   help="episode length for a quick look (default: each scene's horizon)")
    return p


def main(argv: Sequence[str] | None = None) -> Path:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.episodes < 2 or args.grid < 2:
        parser.error("need --seeds >= 1, --episodes >= 2 and --grid >= 2")
    if args.max_steps is not None and args.max_steps < 1:
        parser.error("--max-steps must be >= 1")
    base = {} if args.max_steps is None else {"max_episode_steps": args.max_steps}
    try:
        check_output_dir("--out", args.out)
    except ValueError as e:
        parser.error(str(e))
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    search = {"n_u0": args.grid, "n_nu": args.grid, "episodes": args.search_episodes}
    results = {s: evaluate_scene(s, args.runs, args.out, args.seeds, args.episodes, search,
                                 base) for s in args.scenes}
    gen = {} if args.no_generalisation else {
        s: evaluate_generalisation(s, args.runs, args.seeds, args.episodes, base)
        for s in args.scenes if run_group(args.runs, "ppo_rand", s)}
    lines = ["# Control benchmark: controllers × scenes", "",
             "Made by `python -m fricenv_agents.benchmark` (see its docstring and "
             "docs/control.md).",
             "", *main_tables(results, args.seeds, args.episodes), *gap_lines(results)]
    if gen:
        lines += generalisation_lines(gen)
    plot_returns(results, args.out / "control_benchmark.png")
    lines += ["![control_benchmark.png](control_benchmark.png)", ""]
    if gen:
        plot_generalisation(gen, args.out / "control_generalisation.png")
        lines += ["![control_generalisation.png](control_generalisation.png)", ""]
    table = args.out / "control_benchmark.md"
    table.write_text("\n".join(lines))
    meta = {"n_seeds": args.seeds, "episodes": args.episodes, "env_kwargs": base,
            "seconds": round(time.perf_counter() - t0, 1), "noise": NOISE, "delay": DELAY,
            "held_out": {s: _boxes(s) for s in gen}}
    (args.out / "control_benchmark.json").write_text(
        json.dumps(to_json(results, gen, meta), indent=1, default=str))
    print("\n".join(lines))
    return table


if __name__ == "__main__":
    main()
