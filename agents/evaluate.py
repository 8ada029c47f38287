"""Evaluate trained agents against the baselines; write a markdown table and plots.

    python -m fricenv_agents.evaluate --scene self_excited --runs out/runs/ppo_self_excited_s* \\
        --seeds 5 --episodes 10 --out out/eval

Every controller runs the same episodes: evaluation seed k (k < ``--seeds``) starts
``--episodes`` episodes, episode j from plant seed ``10_000_000 + 1000 k + j`` (never a
training or best-constant-search seed; this is checked against each run's config). A group
of trained runs (same algorithm and scene, one run per training seed) runs every model on
every episode. The table reports mean ± std over all evaluated episodes (models x seeds x
episodes) per controller and scene. Episodes have the scene's own length (400 control
steps for ``self_excited``), whatever length the runs trained on (``max_episode_steps`` in
a run's ``env_kwargs`` applies to its training only); ``--max-steps`` sets another.

- stick-time fraction: time stuck / episode time (exact, from the event-driven plant);
- RMS relative velocity: sqrt of the time mean of (v - V)^2 (steady sliding gives V);
- RMS fluctuation: the same about the episode's mean relative velocity (vibration);
- actuation effort: mean excitation power relative to the strongest allowed, in [0, 1];
- return: the scene's reward summed over the episode.

Outputs in ``--out``: ``<scene>.md``, ``<scene>_results.json`` (per-episode values),
``<scene>_time_history.png`` (one episode, uncontrolled against controlled),
``<scene>_learning_curves.png`` (if runs are given) and the cached best-constant search
(``best_constant_<scene>.json``, ``regime_map_<scene>.npz``).
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from fricenv.checks import check_output_dir

from .cli import HelpFormatter, Stages
from .layout import (
    BASELINES,
    MAX_PLANTS,
    PRETRAINED_PREFIX,
    SCENE_ENV_IDS,
    SEARCH_SEED_BASE,
    SEED_STRIDE,
    check_disjoint,
    eval_env_seed,
    model_path,
    pretrained_names,
)

if TYPE_CHECKING:
    from .scoring import Entry

    Prepared = dict[str, tuple[list[Entry], dict]]  #: scene -> trained entries, env kwargs


# -- CLI --------------------------------------------------------------------------------------
def _model_arg(text: str) -> Path:
    try:
        return model_path(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog or "python -m fricenv_agents.evaluate", description=__doc__.split("\n\n")[0],
        formatter_class=HelpFormatter)
    p.add_argument("--scene", nargs="+", choices=sorted(SCENE_ENV_IDS), default=None,
                   help="scene(s) to evaluate (default: those of the runs)")
    p.add_argument("--runs", nargs="*", type=Path, default=[],
                   help="run folders of fricenv_agents.train (grouped by algorithm)")
    names = ", ".join(PRETRAINED_PREFIX + n for n in pretrained_names())
    p.add_argument("--models", nargs="*", type=_model_arg, default=[], metavar="MODEL",
                   help="model files (<algo>_*.zip, optional <stem>_vecnormalize.pkl and "
                        f"<stem>.yml beside them), or a shipped model by name: {names}")
    p.add_argument("--controllers", nargs="*", choices=BASELINES, default=list(BASELINES),
                   help="baselines to include")
    p.add_argument("--seeds", type=int, default=5, help="evaluation seeds")
    p.add_argument("--episodes", type=int, default=10, help="episodes per evaluation seed")
    p.add_argument("--max-steps", type=int, default=None, metavar="N",
                   help="episode length in control steps (default: the scene's, e.g. 400 "
                        "for self_excited, whatever the runs trained on)")
    p.add_argument("--out", type=Path, default=Path("out/eval"), help="output folder")
    p.add_argument("--no-plots", action="store_true", help="write only the table and json")
    p.add_argument("--grid", type=int, default=21,
                   help="best-constant search: grid points per action dimension")
    p.add_argument("--search-episodes", type=int, default=16,
                   help="best-constant search: episodes per candidate")
    p.add_argument("--quiet", action="store_true",
                   help="no progress lines or bars on stderr (the table still prints)")
    return p


def prepare(args: argparse.Namespace, stage: Callable[[str], None] | None = None,
            ) -> Prepared:
    """Check the command line, load the models and check they fit their scenes
    (``ValueError`` if anything is bad, before the output folder is made); returns the
    scenes to evaluate with their trained entries. ``stage``: told when loading starts."""
    if args.seeds < 1 or args.episodes < 1:
        raise ValueError("need --seeds >= 1 and --episodes >= 1")
    if args.episodes > MAX_PLANTS or args.seeds > (SEARCH_SEED_BASE - eval_env_seed(0)) // (
            SEED_STRIDE):
        raise ValueError(f"need --episodes <= {MAX_PLANTS} and fewer seeds")
    if args.grid < 2 or args.search_episodes < 2:
        raise ValueError("need --grid >= 2 and --search-episodes >= 2")
    if args.max_steps is not None and args.max_steps < 1:
        raise ValueError(f"--max-steps must be >= 1, got {args.max_steps}")
    check_output_dir("--out", args.out)
    from .runs import locate_model

    configs = {}
    for p in [*args.runs, *args.models]:
        if not p.exists():
            raise ValueError(f"{p} does not exist")
        _, cfg, _ = locate_model(p)  # what is missing, before any evaluation runs
        check_disjoint(cfg, args.seeds, args.episodes, p)
        configs[p] = cfg
    scenes = args.scene
    if scenes is None:
        found = []
        for cfg in configs.values():
            if cfg.get("scene") and cfg["scene"] not in found:
                found.append(cfg["scene"])
        if not found:
            raise ValueError("give --scene (no run folder names one)")
        scenes = found
    else:  # a run named for another scene would be left out of every table
        for p, cfg in configs.items():
            if cfg.get("scene", scenes[0]) not in scenes:
                raise ValueError(f"{p} was trained on scene {cfg['scene']!r}, not on "
                                 f"{' or '.join(map(repr, scenes))}")
    if not args.runs and not args.models and not args.controllers:
        raise ValueError("nothing to evaluate: give --runs, --models or --controllers")
    paths = [*args.runs, *args.models]
    from .scoring import load_models, trained_entries

    if paths and stage is not None:
        stage(f"loading {len(paths)} model{'s' if len(paths) > 1 else ''} "
              "(stable-baselines3)")
    loaded = load_models(paths)
    return {scene: trained_entries(paths, scene, loaded) for scene in scenes}


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> list[Path]:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    stage = Stages(parser.prog, args.quiet)
    try:
        prepared = prepare(args, stage)
    except ValueError as e:
        parser.error(str(e))
    from .scoring import evaluate_scene

    made = not args.out.exists()
    try:
        tables = [evaluate_scene(scene, args, trained, stage)
                  for scene, trained in prepared.items()]
        stage(f"wrote {', '.join(str(t) for t in tables)} and their json and plots")
        return tables
    except ValueError as e:  # found only while evaluating: still no traceback, no empty --out
        if made and args.out.is_dir() and not any(args.out.iterdir()):
            args.out.rmdir()
        parser.error(str(e))


if __name__ == "__main__":
    main()
