"""Command line of the atlas: ``fricenv atlas ...`` or ``python -m fricenv.atlas ...``.

Example (the Stribeck volume of the paper's Fig. 10 at four eta)::

    python -m fricenv.atlas --law stribeck --axis u0=geom:0.1:1000:200 \\
        --axis nu=lin:0.1:4:200 --axis eta=0.111,0.2,0.6,2.333 --out atlas.zarr \\
        [--scheduler ADDRESS | --local-workers N]

Follows the subcommand convention of ``fricenv.cli``: :func:`add_arguments` fills a
parser, :func:`run` runs the parsed arguments and returns the exit code.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import numpy as np

from ..checks import check_finite_real
from ..params import OscillatorParams
from ..sweep import SweepSettings

#: Most points one ``--axis`` spec may generate (a typo such as 1e9 would fill memory).
MAX_AXIS_POINTS = 10_000_000


def parse_axis(spec: str) -> tuple[str, np.ndarray]:
    """``NAME=geom:START:STOP:N``, ``NAME=lin:START:STOP:N`` or ``NAME=V1,V2,...`` as the
    axis name and its grid; ``ValueError`` naming the spec otherwise."""
    name, sep, rest = spec.partition("=")
    name = name.strip()
    if not sep or not name or not rest:
        raise ValueError(f"--axis {spec!r}: expected NAME=geom:START:STOP:N, "
                         "NAME=lin:START:STOP:N or NAME=V1,V2,...")
    kind, _, args = rest.partition(":")
    try:
        if kind in ("geom", "lin"):
            parts = args.split(":")
            if len(parts) != 3:
                raise ValueError(f"{kind} needs START:STOP:N")
            start, stop = (check_finite_real(name, float(p)) for p in parts[:2])
            n = int(parts[2])
            if not 1 <= n <= MAX_AXIS_POINTS:
                raise ValueError(f"N must be in [1, {MAX_AXIS_POINTS}], got {n}")
            if kind == "geom" and (start <= 0 or stop <= 0):
                raise ValueError("a geometric grid needs START > 0 and STOP > 0")
            grid = (np.geomspace if kind == "geom" else np.linspace)(start, stop, n)
        else:
            grid = np.array([float(v) for v in rest.split(",")])
    except ValueError as exc:
        raise ValueError(f"--axis {spec!r}: {exc}") from None
    return name, grid


def parse_pairs(option: str, pairs: Sequence[str]) -> dict[str, object]:
    """``KEY=VALUE`` strings as a dict (numbers as float, else the text)."""
    out: dict[str, object] = {}
    for item in pairs:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"{option} {item!r}: expected KEY=VALUE")
        try:
            out[key.strip()] = int(value) if value.strip().lstrip("-").isdigit() \
                else float(value)
        except ValueError:
            out[key.strip()] = value.strip()
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--law", default="coulomb",
                        help="friction law of the paper's Fig. 2 (coulomb, viscous, "
                             "stribeck); default coulomb")
    parser.add_argument("--axis", action="append", required=True, metavar="NAME=SPEC",
                        help="a swept parameter and its grid: geom:START:STOP:N, "
                             "lin:START:STOP:N or V1,V2,... (repeat; order = dims)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a fixed parameter other than the law's default (repeat)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        dest="settings", help="a sweep setting (SweepSettings; repeat)")
    parser.add_argument("--out", required=True, help="Zarr store to write (a folder); "
                        "run again to resume")
    parser.add_argument("--chunks", type=int, default=None,
                        help="cells per chunk (default: automatic, or the store's)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="a running Dask scheduler (tcp://host:8786); default: "
                            "this machine's threads")
    where.add_argument("--local-workers", type=int, default=None, metavar="N",
                       help="start a local Dask cluster of N single-threaded workers")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from .api import atlas  # (zarr and xarray load here, not with the parser)

    try:
        axes = dict(parse_axis(a) for a in args.axis)
        if len(axes) != len(args.axis):
            raise ValueError("--axis: a parameter is given twice")
        base = OscillatorParams.preset(args.law, **parse_pairs("--param", args.param))
        settings = SweepSettings(**parse_pairs("--set", args.settings))
    except (TypeError, ValueError) as exc:
        print(f"fricenv atlas: error: {exc}", file=sys.stderr)
        return 2
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
                   settings=settings, progress=not args.no_progress)
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fricenv.atlas",
                                     description="Regime atlas over any parameter volume, "
                                                 "into a resumable Zarr store.")
    add_arguments(parser)
    return run(parser.parse_args(argv))
