"""``fricenv atlas``: a regime atlas over any parameter volume (needs ``fricenv[scale]``)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from fricenv.cli import _notice
from fricenv.cli._args import interrupted
from fricenv.compile_notice import method_for_law


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    try:
        from fricenv.atlas import cli
    except ImportError as e:
        p = argparse.ArgumentParser(prog=prog)
        p.error(f"the atlas needs the scale extra (pip install 'fricenv[scale]'): {e}")
    p = cli.build_parser(prog)
    args = p.parse_args(argv)
    _notice.announce(lambda: [("sweep", method_for_law(args.law or "coulomb"))])
    try:
        return cli.run(args)
    except KeyboardInterrupt as e:  # (SweepInterrupted: the finished chunks are stored)
        return interrupted(p.prog, e, f"finished chunks are in {args.out} (rerun to resume)")
