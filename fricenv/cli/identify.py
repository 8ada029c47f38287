"""``fricenv identify``: which friction law produced a measured record, as a report.

Reads a CSV record (columns ``t`` and ``x``, optionally ``v``; a header line names them),
fits every candidate law on the exact simulator and writes ``report.md`` and
``identification.png`` into ``--out``. Example::

    fricenv identify record.csv --known eta=0.6,nu=0.1,u0=1.15,V=1 --out out/identify
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fricenv.cli._args import out_dir, parser


def known_settings(text: str) -> dict[str, float]:
    """``eta=0.6,nu=0.1,u0=1.15,V=1`` as a dict; ``ArgumentTypeError`` naming a bad item."""
    out: dict[str, float] = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise argparse.ArgumentTypeError(f"{item!r} is not NAME=VALUE")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{item!r}: {value!r} is not a number") from None
    return out


def read_record(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """t, x and v (None without a ``v`` column) of a CSV record whose header names them."""
    with path.open(encoding="utf-8") as f:
        header = [h.strip().lower() for h in f.readline().split(",")]
    if "t" not in header or "x" not in header:
        raise ValueError(f"{str(path)!r}: the header must name columns t and x (and v if "
                         f"measured), got {header}")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    v = data[:, header.index("v")] if "v" in header else None
    return data[:, header.index("t")], data[:, header.index("x")], v


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = parser(prog, "Identify the friction law and its parameters from a measured record, "
                     "and write a report (Markdown and a figure).",
               ["fricenv identify record.csv --known eta=0.6,nu=0.1,u0=1.15,V=1"])
    p.add_argument("record", type=Path, help="CSV with a header naming t, x (and v)")
    p.add_argument("--known", type=known_settings, required=True,
                   help="the rig's settings: eta, nu, u0 (or u1, u2) and V")
    p.add_argument("--laws", nargs="+", default=None,
                   help="candidate laws (default: coulomb viscous stribeck exponential)")
    p.add_argument("--no-v", action="store_true", help="ignore a v column")
    p.add_argument("--out", type=out_dir, default=Path("out/identify"), help="report folder")
    return p


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    parser_ = build_parser(prog)
    args = parser_.parse_args(argv)
    from fricenv.identification import DEFAULT_LAWS, identify
    from fricenv.identification.report import write_report

    try:
        if not args.record.is_file():
            raise ValueError(f"record {str(args.record)!r} is not a file")
        t, x, v = read_record(args.record)
        res = identify(t, x, known=args.known, v=None if args.no_v else v,
                       laws=tuple(args.laws) if args.laws else DEFAULT_LAWS)
    except (TypeError, ValueError) as e:
        parser_.error(str(e))
    print(res.summary())
    path = write_report(res, args.out, source=args.record.name)
    print(f"wrote {path} and {args.out / 'identification.png'}")
    return 0
