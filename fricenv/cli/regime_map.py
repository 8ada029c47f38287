"""``fricenv map``: one regime-map panel over a u0 x nu grid, for any law and plant.

Writes ``map.npz`` (resumable: rerun the same command after an interruption and only the
missing cells are computed) and ``map.png`` into ``--out``. Example::

    fricenv map --law stribeck --set eta=0.6 --u0 geom:0.1:1000:120 --nu lin:0.02:4:120

Progress: a line before the sweep and before the figure, and the sweep's progress bar,
on stderr; ``--quiet`` silences them with the compile notice.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

from fricenv.cli import _notice
from fricenv.cli._args import add_plant_arguments, grid, interrupted, out_dir, parser, plant
from fricenv.compile_notice import method_for_law


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = parser(prog, "Compute one regime-map panel over a u0 x nu grid and draw it "
                     "(resumable).",
               ["fricenv map --law stribeck --set eta=0.6 --u0 geom:0.1:1000:120 "
                "--nu lin:0.02:4:120"])
    add_plant_arguments(p, cases=False)
    p.add_argument("--u0", type=grid, required=True, metavar="SPEC",
                   help="u0 grid: geom:START:STOP:N, lin:START:STOP:N or a,b,c")
    p.add_argument("--nu", type=grid, required=True, metavar="SPEC", help="nu grid, as --u0")
    p.add_argument("--out", type=out_dir, default=Path("out/map"), help="output folder")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all)")
    p.add_argument("--quiet", action="store_true",
                   help="no compile notice, progress bar or stage lines")
    p.add_argument("--restart", action="store_true",
                   help="recompute every cell instead of resuming from map.npz")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (the stage lines stay)")
    return p


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    try:
        params = plant(args)
        _notice.stage(f"map: {args.u0.size} x {args.nu.size} cells, {params.law} law, "
                      f"into {args.out / 'map.npz'}")
        import fricenv

        args.out.mkdir(parents=True, exist_ok=True)
        _notice.announce(lambda: [("sweep", method_for_law(params.law))])
        t0 = time.perf_counter()
        m = fricenv.regime_map(params, args.u0, args.nu, path=args.out / "map.npz",
                               resume=not args.restart, n_threads=args.threads,
                               progress=not (args.no_progress or args.quiet))
    except (TypeError, ValueError) as e:
        parser.error(str(e))
    except KeyboardInterrupt as e:
        return interrupted(parser.prog, e, f"cells done so far are in {args.out / 'map.npz'} "
                                           "(rerun to resume)")
    _notice.stage(f"map: drawing {args.out / 'map.png'}")
    from fricenv import plotting

    title = plotting.params_title(params).split(":")[0] + f", η = {params.eta:.4g}"
    png = plotting.save(plotting.regime_maps_figure([m], titles=[title]),
                        args.out / "map.png")
    counts = ", ".join(f"{k} {v}" for k, v in m.counts().items() if v)
    print(f"{m.shape[0]} x {m.shape[1]} cells: {counts}")
    print(f"wrote {args.out / 'map.npz'} and {png} ({time.perf_counter() - t0:.1f} s)")
    return 0
