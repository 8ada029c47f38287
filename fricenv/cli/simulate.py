"""``fricenv simulate``: the time history of one plant, as a figure and as data.

Writes ``time_history.png`` and ``trajectory.npz`` (or ``trajectory.csv``) into ``--out``
and prints the run's summary. Example::

    fricenv simulate --case 5a --t-end 200 --out out/fig5a
    fricenv simulate --law stribeck --set eta=0.111 --set u0=2 --set nu=0.5 --format csv
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fricenv.cli import _notice
from fricenv.cli._args import add_plant_arguments, number, out_dir, parser, plant
from fricenv.layout import METHODS

if TYPE_CHECKING:
    from fricenv.simulate import Trajectory


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = parser(prog, "Simulate one plant from rest and write its time history as a figure "
                     "and as data.",
               ["fricenv simulate --case 5a --t-end 200 --out out/fig5a",
                "fricenv simulate --law stribeck --set eta=0.111 --set u0=2 --format csv"])
    add_plant_arguments(p, cases=True)
    p.add_argument("--t-end", type=number, default=200.0,
                   help="end time, dimensionless (from rest at 0)")
    p.add_argument("--method", default="auto", choices=["auto", *METHODS],
                   help="integration method")
    p.add_argument("--dt-out", type=number, default=0.1, help="output spacing, dimensionless time")
    p.add_argument("--out", type=out_dir, default=Path("out/simulate"), help="output folder")
    p.add_argument("--format", default="npz", choices=["npz", "csv"], help="data format")
    return p


def write_data(tr: Trajectory, path: Path, fmt: str) -> Path:
    """The trajectory's samples (t, x, v, mode) and events, as npz or CSV (events in a
    second file ``<stem>_events.csv``, whose ``kind`` codes come with their names, so that
    the file reads without the package: 1 stick, 2 slip, 3 reversal)."""
    if fmt == "npz":
        path = path.with_suffix(".npz")
        np.savez(path, t=tr.t, x=tr.x, v=tr.v, mode=tr.mode, event_t=tr.event_t,
                 event_kind=tr.event_kind, event_x=tr.event_x)
        return path
    path = path.with_suffix(".csv")
    np.savetxt(path, np.column_stack([tr.t, tr.x, tr.v, tr.mode]), delimiter=",",
               header="t,x,v,mode", comments="", fmt=["%.17g", "%.17g", "%.17g", "%d"])
    from fricenv.simulate import EVENT_NAMES

    lines = ["t,kind,name,x"] + [
        f"{t:.17g},{int(k)},{EVENT_NAMES.get(int(k), 'unknown')},{x:.17g}"
        for t, k, x in zip(tr.event_t, tr.event_kind, tr.event_x, strict=True)]
    path.with_name(path.stem + "_events.csv").write_text("\n".join(lines) + "\n")
    return path


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    import fricenv
    from fricenv import plotting
    from fricenv.simulate import resolve_method

    try:
        params = plant(args)
        try:  # before the run: a folder that cannot be made would lose it
            args.out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise ValueError(f"--out {str(args.out)!r} cannot be made: {e}") from None
        _notice.announce(lambda: [("simulate", resolve_method(params, args.method))])
        tr = fricenv.simulate(params, args.t_end, method=args.method, dt_out=args.dt_out)
    except (TypeError, ValueError) as e:
        parser.error(str(e))
    except fricenv.SimulationError as e:
        parser.exit(1, f"{parser.prog}: error: {e}\n")
    data = write_data(tr, args.out / "trajectory", args.format)
    # (the panel's title names the law and the parameters; the figure's adds the run's facts)
    title = (f"{tr.method} method, τ from 0 to {args.t_end:g}, stick-time fraction "
             f"{tr.stick_fraction:.3f}")
    png = plotting.save(plotting.time_history_figure([tr], suptitle=title),
                        args.out / "time_history.png")
    for key, value in tr.summary().items():
        print(f"{key:>16}: {value}")
    print(f"wrote {png} and {data}")
    return 0
