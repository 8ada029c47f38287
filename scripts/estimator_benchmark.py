"""Stick cut kept under sensor noise and delay by the MPC with a particle filter in front.

    python scripts/estimator_benchmark.py [--scenes paper self_excited stribeck viscous]
        [--seeds 2] [--episodes 10] [--max-steps N] [--particles 1000]
        [--plan-from posterior] [--json out/estimator_benchmark.json]

On each scene, plants drawn from the scene's randomisation ranges (``randomize=True``)
and the control benchmark's evaluation episodes: the stick cut against zero excitation
of (a) the MPC bound to the exact state without sensors, (b) the MPC planning from the
raw noisy, delayed reading, (c) ``fricenv_agents.estimation.FilteredMPC``, under the
benchmark's sensor noise and one-interval delay (``fricenv_agents.benchmark.NOISE`` and
``DELAY``); retention is a cut over (a)'s. Also the RMS errors of x and v - V of the
filter's posterior mean and of the raw reading against the exact current state. Prints
the table (docs/control.md shows it) and writes every number, per-episode stick fractions
included, to ``--json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from fricenv_agents.benchmark import BENCH_SCENES, DELAY, NOISE
from fricenv_agents.estimation import DEFAULT_PARTICLES, PLAN_FROM, noise_retention


def table(results: list[dict]) -> list[str]:
    lines = ["| scene | episodes | cut, exact state | cut, raw reading | cut, filtered | "
             "retention, raw | retention, filtered | RMS x, filter / raw | "
             "RMS v − V, filter / raw |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        c, q, e = r["cut"], r["retention"], r["rms"]
        lines.append(f"| `{r['scene']}` | {r['episodes']} | {100 * c['exact']:.1f} % | "
                     f"{100 * c['raw']:.1f} % | {100 * c['filtered']:.1f} % | "
                     f"{100 * q['raw']:.0f} % | {100 * q['filtered']:.0f} % | "
                     f"{e['x']:.3f} / {e['raw_x']:.3f} | {e['v_rel']:.3f} / {e['raw_v_rel']:.3f} |")
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenes", nargs="+", choices=BENCH_SCENES, default=list(BENCH_SCENES))
    p.add_argument("--seeds", type=int, default=2, help="evaluation seeds")
    p.add_argument("--episodes", type=int, default=10, help="episodes per evaluation seed")
    p.add_argument("--max-steps", type=int, default=None,
                   help="episode length for a quick look (default: each scene's horizon)")
    p.add_argument("--particles", type=int, default=DEFAULT_PARTICLES)
    p.add_argument("--plan-from", choices=PLAN_FROM, default=PLAN_FROM[0])
    p.add_argument("--json", type=Path, default=None, help="file for the results")
    args = p.parse_args()
    if args.seeds < 1 or args.episodes < 1:
        p.error(f"need --seeds >= 1 and --episodes >= 1, got {args.seeds} and {args.episodes}")
    if args.max_steps is not None and args.max_steps < 1:
        p.error(f"--max-steps must be >= 1, got {args.max_steps}")
    base: dict = {"randomize": True}
    if args.max_steps is not None:
        base["max_episode_steps"] = args.max_steps
    sensors = {"obs_noise": NOISE, "obs_delay": DELAY}
    results = []
    for scene in args.scenes:
        r = noise_retention(scene, args.seeds, args.episodes, base, sensors,
                            particles=args.particles, plan_from=args.plan_from)
        results.append(r)
        print("\n".join(table([r])[2:]), r["seconds"], flush=True)
    lines = ["# MPC with a particle filter under sensor noise and delay", "",
             "Made by `python scripts/estimator_benchmark.py` (see its docstring). Noise: "
             f"{NOISE}, delay {DELAY} interval; plants from the scenes' randomisation ranges.",
             "", *table(results), ""]
    print("\n".join(lines))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        meta = {"env_kwargs": base, "noise": NOISE, "delay": DELAY, "seeds": args.seeds,
                "episodes": args.episodes}
        args.json.write_text(json.dumps({**meta, "results": results}, indent=1))


if __name__ == "__main__":
    main()
