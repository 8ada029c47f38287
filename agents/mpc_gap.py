"""Closing PPO's gap to the tuned MPC: new PPO runs scored on the benchmark's episodes and
compared with the tuned MPC exactly as ``fricenv_agents.mpc_compare`` compares the shipped
benchmark runs.

    python -m fricenv_agents.mpc_gap [--runs agents/pretrained/short]
        [--scenes stribeck viscous] [--csv docs/results/control_benchmark_episodes.csv]
        [--tuned docs/results/mpc_tuned_episodes.csv] [--out out/mpc-gap]

The runs (``<runs>/ppo_<scene>_s<seed>/``, trained with ``fricenv train --hyperparams
agents/hyperparams/ppo_short.yml``) are scored on the benchmark's nominal evaluation
episodes (its 10 evaluation seeds x 5 episodes, every run on every episode, through
``fricenv_agents.scoring``, refusing any episode a run trained or was monitored on), as
controller ``ppo_short``. The tuned MPC's rows are those ``mpc_compare`` ran on the same
episodes (``mpc_tuned_episodes.csv``); PPO's shipped benchmark runs (controller ``ppo``)
give the gap before. Per scene and for both, the statistics of
``mpc_compare.compare_scene``: IQM and mean with their paired gap intervals, CVaR, the
share of paired episodes won. The page also states each recipe's compute from the runs'
``config.yml`` (training steps, training episode length, the MPC labels of a warm start,
wall time).

Writes ``mpc_gap_episodes.csv`` (the new runs' episodes, in the benchmark's CSV format),
``mpc_gap.json`` and ``mpc_gap.md`` to ``--out``. A scene already in ``--out``'s CSV is not
scored again, so the page can be remade without loading a model.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from . import statistics as S
from .benchmark_records import episode_grid, episode_rows, read_episodes, write_report
from .cli import HelpFormatter, Stages
from .layout import check_disjoint, check_scene
from .mpc_compare import (
    BOOT_SEED,
    DEFAULT_CSV,
    TAIL,
    _fmt,
    _write_csv,
    compare_scene,
    sentence,
)
from .mpc_compare import (
    CSV_NAME as TUNED_CSV_NAME,
)

KEY = "ppo_short"
CSV_NAME = "mpc_gap_episodes.csv"
RESULTS = DEFAULT_CSV.parent
DEFAULT_RUNS = Path(__file__).resolve().parent / "pretrained" / "short"
SCENES = ("stribeck", "viscous", "paper")


def scene_runs(root: Path, scene: str) -> list[Path]:
    """The finished run folders of ``scene`` under ``root`` (``ppo_<scene>_s<seed>`` with
    a ``config.yml`` and a ``model.zip``), by seed."""
    runs = [p for p in root.glob(f"ppo_{scene}_s*")
            if (p / "config.yml").exists() and (p / "model.zip").exists()]
    return sorted(runs, key=lambda p: int(p.name.rsplit("_s", 1)[1]))


def score_runs(runs: list[Path], scene: str, n_seeds: int,
               episodes: int) -> list[dict[str, Any]]:
    """The runs of ``scene`` on the benchmark's nominal evaluation episodes, as CSV rows of
    controller ``KEY``; ``ValueError`` if there are none or one trained on an episode."""
    from .scoring import run_entry, trained_entries

    if not runs:
        raise ValueError(f"no runs of scene {scene!r} (ppo_{scene}_s<seed>/)")
    for p in runs:
        config = yaml.safe_load((p / "config.yml").read_text()) or {}
        check_disjoint(config, n_seeds, episodes, str(p))
    entries, env_kwargs = trained_entries(runs, scene)
    if len(entries) != 1:
        raise ValueError(f"{scene}: expected one group of PPO runs, got "
                         f"{[e.key for e in entries]}")
    entry = entries[0]
    run_entry(entry, scene, env_kwargs, n_seeds, episodes)
    label = f"PPO, short training episodes ({len(runs)} training seeds)"
    return [dict(r, controller=KEY, label=label)
            for r in episode_rows(scene, "nominal", entry)]


def recipe(runs: list[Path]) -> dict[str, Any]:
    """What the runs of a scene cost and how they trained, from their ``config.yml``."""
    configs = [yaml.safe_load((p / "config.yml").read_text()) or {} for p in runs]
    first = configs[0]
    warm = first.get("warm_start")
    out: dict[str, Any] = {
        "runs": [p.name for p in runs],
        "hyperparams_file": first.get("hyperparams_file"),
        "timesteps": int(first.get("n_timesteps") or 0),
        "episode_steps": (first.get("env_kwargs") or {}).get("max_episode_steps"),
        "learning_rate": (first.get("hyperparams") or {}).get("learning_rate"),
        "train_seconds": [float(c.get("train_seconds") or 0.0) for c in configs],
        "warm_start": None,
    }
    if warm:
        out["warm_start"] = {
            "rounds": warm["rounds"], "steps": warm.get("steps"),
            "labels": int(warm["env_steps"]),
            "seconds": [float((c.get("warm_start") or {}).get("seconds", 0.0))
                        for c in configs]}
    return out


def describe(r: dict[str, Any]) -> str:
    """A recipe in words, with its compute per run."""
    secs = r["train_seconds"]
    text = (f"{r['timesteps'] / 1e6:g}M PPO steps on training episodes of "
            f"{r['episode_steps']} intervals, {sum(secs) / len(secs) / 60:.1f} min of PPO "
            "per run")
    w = r["warm_start"]
    if w:
        ws = w["seconds"]
        text = (f"DAgger from the tuned MPC ({w['rounds']} rounds of the first "
                f"{w['steps'] or r['episode_steps']} intervals of 16 plants: {w['labels']} MPC "
                f"labels, {sum(ws) / len(ws) / 60:.1f} min per run), then " + text)
    return text


def _count(results: dict[str, dict[str, Any]]) -> str:
    """How many new runs each scene has, in words for the page."""
    counts = {len(r["recipe"]["runs"]) for r in results.values()}
    return str(counts.pop()) if len(counts) == 1 else "/".join(
        str(len(r["recipe"]["runs"])) for r in results.values())


def markdown(results: dict[str, dict[str, Any]]) -> str:
    """The page: the gap before and after, then each recipe and its compute."""
    lines = [
        "# Closing PPO's gap to the tuned MPC",
        "",
        "Made by `python -m fricenv_agents.mpc_gap` (see its docstring). Nominal condition, "
        "the benchmark's 10 evaluation seeds × 5 episodes, every run on every episode. "
        "Before: the benchmark's five PPO runs (`agents/pretrained/benchmark/`); after: "
        f"{_count(results)} PPO runs trained on short episodes (`agents/pretrained/short/`, "
        "`agents/hyperparams/ppo_short.yml`). Both against the tuned MPC on the same "
        "plants ([mpc_tuned_episodes.csv](mpc_tuned_episodes.csv)), with the statistics "
        "of [PPO against the tuned MPC](mpc_compare.md): gap = (MPC − PPO) / |MPC|, "
        "negative when PPO does better; 95 % intervals from 2000 bootstrap replicates "
        "over training runs and, within each evaluation seed's block, episodes, paired "
        "over the shared episodes. No choice of recipe, training length or run used an "
        "evaluation episode: the recipes were compared on episodes of the training "
        "seeds' monitoring blocks.",
        "",
        "| scene | PPO | PPO, IQM | gap by IQM | PPO, mean | gap by mean | "
        "CVaR 5 %, PPO / MPC | worst episode, PPO / MPC | PPO wins |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for scene, res in results.items():
        for name, r in (("before", res["before"]), ("after", res["after"])):
            lines.append(
                f"| `{scene}` | {name} | {_fmt(r['iqm_learned'])} | "
                f"{_fmt(r['gap_iqm'], 1, 100, ' %', True)} | {_fmt(r['mean_learned'])} | "
                f"{_fmt(r['gap_mean'], 1, 100, ' %', True)} | "
                f"{r['cvar_learned']:.2f} / {r['cvar_ref']:.2f} | "
                f"{r['worst_learned']:.2f} / {r['worst_ref']:.2f} | "
                f"{_fmt(r['win_share'], 0, 100, ' %')} |")
    lines += ["", "The tuned MPC's IQM and mean, for reference: " + "; ".join(
        f"`{s}` {_fmt(res['after']['iqm_ref'])} and {_fmt(res['after']['mean_ref'])}"
        for s, res in results.items()) + ".", ""]
    lines += [sentence(s, res["after"]).replace("PPO is", "PPO trained on short episodes is",
                                                1) for s, res in results.items()]
    lines += ["", "## The recipes and their compute", "",
              "Per scene, the hyperparameter file's entry, as every run's `config.yml` "
              "records it; wall times on the shared 2-core machine, each run on one "
              "core:", ""]
    lines += [f"- `{s}`: {describe(res['recipe'])}." for s, res in results.items()]
    lines.append("")
    return "\n".join(lines)


def compare(rows: list[dict[str, Any]], scene: str, runs: list[Path]) -> dict[str, Any]:
    """Before (the benchmark's ``ppo``) and after (``KEY``) against the tuned MPC."""
    return {"before": compare_scene(rows, scene, learned="ppo"),
            "after": compare_scene(rows, scene, learned=KEY), "recipe": recipe(runs)}


def main(argv: Sequence[str] | None = None) -> Path:
    p = argparse.ArgumentParser(prog="python -m fricenv_agents.mpc_gap",
                                description=__doc__.split("\n\n")[0],
                                formatter_class=HelpFormatter)
    p.add_argument("--runs", type=Path, default=DEFAULT_RUNS,
                   help="folder of the new runs (ppo_<scene>_s<seed>/)")
    p.add_argument("--scenes", nargs="+", default=list(SCENES))
    p.add_argument("--csv", type=Path, default=DEFAULT_CSV,
                   help="the benchmark's per-episode CSV (the shipped PPO's rows)")
    p.add_argument("--tuned", type=Path, default=RESULTS / TUNED_CSV_NAME,
                   help="the tuned MPC's episodes (made by fricenv_agents.mpc_compare)")
    p.add_argument("--out", type=Path, default=Path("out/mpc-gap"))
    args = p.parse_args(argv)
    for s in args.scenes:
        check_scene(s)
    bench = [r for r in read_episodes(args.csv) if r["condition"] == "nominal"]
    n_seeds, episodes = episode_grid(bench)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / CSV_NAME
    new = read_episodes(path) if path.exists() else []
    say = Stages("mpc_gap")
    for scene in args.scenes:
        if not any(r["scene"] == scene for r in new):
            say(f"{scene}: scoring the runs in {args.runs} on {n_seeds} x {episodes} "
                "episodes")
            new += score_runs(scene_runs(args.runs, scene), scene, n_seeds, episodes)
            _write_csv(path, new)
    rows = bench + read_episodes(args.tuned) + new
    results = {s: compare(rows, s, scene_runs(args.runs, s)) for s in args.scenes}
    return write_report(args.out, "mpc_gap",
                        {"tail": TAIL, "bootstrap": {"replicates": S.N_BOOT, "seed": BOOT_SEED},
                         "scenes": results}, markdown(results))


if __name__ == "__main__":
    main()
