"""``fricenv atlas`` (and ``python -m fricenv.atlas``): a regime atlas over any parameter
volume (needs ``fricenv[scale]``).

It computes the regime of every cell of a grid over any parameters into a resumable Zarr
store, on this machine's threads or a Dask cluster. A line before the run and a progress
bar over the cells go to stderr; ``--quiet`` silences them. Example (the Stribeck volume
of the paper's Fig. 10 at four eta)::

    fricenv atlas --law stribeck --axis u0=geom:0.1:1000:200 \\
        --axis nu=lin:0.1:4:200 --axis eta=0.111,0.2,0.6,2.333 --out atlas.zarr \\
        [--scheduler ADDRESS | --local-workers N]

Follows the subcommand convention of ``fricenv.cli``: :func:`add_arguments` fills a
parser, :func:`run` runs the parsed arguments and returns the exit code. It lives with the
other commands, above the atlas package (``fricenv.atlas`` imports nothing of
``fricenv.cli``); only the atlas's ``__main__`` program reaches it.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from fricenv.cli import _notice
from fricenv.cli._args import (
    add_plant_arguments,
    grid,
    interrupted,
    parser,
    plant,
    positive_int,
    unique_axes,
)
from fricenv.compile_notice import method_for_law
from fricenv.interrupts import interrupts_redelivered

#: The command's description and examples (``--help``).
DESCRIPTION = ("Compute the regime of every cell of a grid over any parameters into a "
               "resumable Zarr store.")
EXAMPLES = ["fricenv atlas --law stribeck --axis u0=geom:0.1:1000:200 "
            "--axis nu=lin:0.1:4:200 --axis eta=0.111,0.2,0.6,2.333 --out atlas.zarr"]


def parse_axis(spec: str) -> tuple[str, np.ndarray]:
    """``NAME=geom:START:STOP:N``, ``NAME=lin:START:STOP:N`` or ``NAME=V1,V2,...`` as the
    axis name and its grid (the grids of ``fricenv map``); ``ValueError`` naming the spec
    otherwise."""
    name, sep, rest = spec.partition("=")
    name = name.strip()
    if not sep or not name or not rest:
        raise ValueError(f"--axis {spec!r}: expected NAME=geom:START:STOP:N, "
                         "NAME=lin:START:STOP:N or NAME=V1,V2,...")
    try:
        return name, grid(rest)
    except argparse.ArgumentTypeError as exc:
        raise ValueError(f"--axis {spec!r}: {exc}") from None


def parse_settings(pairs: Sequence[str]) -> dict[str, Any]:
    """``--setting KEY=VALUE`` strings as a dict (numbers as int or float, else the text,
    as ``SweepSettings`` takes them: ``method=event``, ``n_strobe=24``)."""
    out: dict[str, Any] = {}
    for item in pairs:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"--setting {item!r}: expected KEY=VALUE")
        try:
            out[key.strip()] = int(value) if value.strip().lstrip("-").isdigit() \
                else float(value)
        except ValueError:
            out[key.strip()] = value.strip()
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_plant_arguments(parser, cases=False)
    parser.add_argument("--axis", action="append", required=True, metavar="NAME=SPEC",
                        help="a swept parameter and its grid: geom:START:STOP:N, "
                             "lin:START:STOP:N or V1,V2,...; repeat for each axis, in "
                             "the order of the store's dimensions")
    parser.add_argument("--setting", action="append", default=[], metavar="NAME=VALUE",
                        dest="settings",
                        help="a sweep setting, a field of fricenv.SweepSettings; repeatable")
    parser.add_argument("--out", required=True, help="Zarr store to write (a folder); "
                        "run again to resume")
    parser.add_argument("--chunks", type=int, default=None,
                        help="cells per chunk (default: automatic, or the store's)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="a running Dask scheduler (tcp://host:8786); default: "
                            "this machine's threads")
    where.add_argument("--local-workers", type=positive_int, default=None, metavar="N",
                       help="start a local Dask cluster of N single-threaded workers")
    parser.add_argument("--no-progress", action="store_true",
                        help="no progress bar (the stage line stays)")
    parser.add_argument("--quiet", action="store_true",
                        help="no compile notice, progress bar or stage line")


def run(args: argparse.Namespace) -> int:
    # (the kernels, zarr and xarray load here, not with the parser)
    from fricenv.cells import SweepSettings

    try:
        from fricenv.atlas.api import atlas
    except ImportError as e:
        print(f"fricenv atlas: error: the atlas needs the scale extra "
              f"(pip install 'fricenv[scale]'): {e}", file=sys.stderr)
        return 2

    try:
        axes = unique_axes([parse_axis(a) for a in args.axis])
        base = plant(args)
        settings = SweepSettings(**parse_settings(args.settings))
    except (TypeError, ValueError) as exc:
        print(f"fricenv atlas: error: {exc}", file=sys.stderr)
        return 2
    shape = " x ".join(f"{len(v)} {k}" for k, v in axes.items())
    _notice.stage(f"atlas: {shape} cells, {base.law} law, into {args.out}"
                  + (f" on the Dask scheduler {args.scheduler}" if args.scheduler else
                     f" on {args.local_workers} local Dask workers" if args.local_workers
                     else ""))

    client = cluster = None
    if args.scheduler or args.local_workers:
        from distributed import Client, LocalCluster

        if args.scheduler:
            client = Client(args.scheduler)
        else:
            cluster = LocalCluster(n_workers=args.local_workers, threads_per_worker=1,
                                   processes=True)
            client = Client(cluster)
    t0 = time.perf_counter()
    try:
        ds = atlas(base, axes, path=args.out, client=client, chunks=args.chunks,
                   settings=settings, progress=not (args.no_progress or args.quiet))
    except (TypeError, ValueError) as exc:
        print(f"fricenv atlas: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    dt = time.perf_counter() - t0
    n = int(np.prod(list(ds.sizes.values())))
    print(f"wrote {args.out}: {n} cells {dict(ds.sizes)} in {dt:.1f} s "
          f"({n / dt:.0f} cells/s)")
    return 0


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = parser(prog, DESCRIPTION, EXAMPLES)
    add_arguments(p)
    return p


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """``fricenv atlas``: the compile notice, then the run (``fricenv.cli.main`` prints
    the stage lines)."""
    p = build_parser(prog)
    args = p.parse_args(argv)
    _notice.announce(lambda: [("sweep", method_for_law(args.law or "coulomb"))])
    try:
        return run(args)
    except KeyboardInterrupt as e:  # (SweepInterrupted: the finished chunks are stored)
        return interrupted(p.prog, e, f"finished chunks are in {args.out} (rerun to resume)")


def module_main(argv: Sequence[str] | None = None) -> int:
    """``python -m fricenv.atlas``: as ``fricenv atlas``, stage lines on stderr."""
    p = build_parser("python -m fricenv.atlas")
    args = p.parse_args(argv)
    try:
        with interrupts_redelivered(), _notice.log_to_stderr(quiet=args.quiet):
            return run(args)
    except KeyboardInterrupt as e:  # (SweepInterrupted: the finished chunks are stored)
        return interrupted(p.prog, e, f"finished chunks are in {args.out} (rerun to resume)")
