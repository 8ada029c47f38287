"""``fricenv bench NAME``: run one of the package's benchmarks (:mod:`fricenv.bench`).

Options after the benchmark's name go to it (``fricenv bench NAME --help``); ``--quiet``
silences the progress lines. The exit status is the benchmark's: 1 when a bound it checks
fails.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from fricenv.bench import BENCHMARKS  # (the package's __init__ imports no benchmark)
from fricenv.cli import _notice

#: benchmark name -> the (workload, method) pairs of ``fricenv.compile_notice`` it runs
#: first (for the compile notice; a benchmark may compile more later).
BENCHMARK_NEEDS: dict[str, list[tuple[str, str]]] = {
    "solvers": [("simulate", "exact"), ("simulate", "event"), ("simulate", "rk4")],
    "sweep": [("sweep", "exact")],
    "env": [("env", "exact"), ("vector_env", "exact")],
    "compile": [],  # (each workload compiles in a child process with a cache of its own)
    "derivatives": [("simulate", "event")],
}

DESCRIPTION = "Run one of fricenv's benchmarks and check its bounds."
EXAMPLE = "example:\n  fricenv bench solvers --quick --out out/bench"


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    listing = "\n".join(f"  {k:<11} {v}" for k, v in BENCHMARKS.items())
    p = argparse.ArgumentParser(
        prog=prog, description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"benchmarks:\n{listing}\n\n'fricenv bench NAME --help' shows a benchmark's "
               f"options.\n\n{EXAMPLE}")
    p.add_argument("name", choices=list(BENCHMARKS), help="which benchmark")
    p.add_argument("--quiet", action="store_true", help="no progress lines or bars")
    return p


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = build_parser(prog)
    argv = [a for a in argv if a != "--quiet"]  # (fricenv.cli.main reads it)
    args = p.parse_args(argv[:1] or ["--help"])
    rest = argv[1:]
    if not {"-h", "--help"} & set(rest):
        _notice.stage(f"bench {args.name}: {BENCHMARKS[args.name]}")
        _notice.announce(BENCHMARK_NEEDS[args.name])
    module = importlib.import_module(f"fricenv.bench.{args.name}")
    try:
        status = module.main(rest, prog=f"{prog or 'fricenv bench'} {args.name}")
    except SystemExit as e:  # (argparse: --help, a usage error)
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    return int(status or 0)
