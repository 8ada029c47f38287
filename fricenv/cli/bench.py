"""``fricenv bench NAME``: the benchmark scripts of a source checkout.

The benchmarks compare fricenv with an independent SciPy solution that lives with the
tests, so they run from a clone of the repository (``scripts/bench_*.py``), not from an
installed wheel. Options after the benchmark's name go to its script; see
``fricenv bench NAME --help``.
"""

from __future__ import annotations

import argparse
import runpy
import sys
from collections.abc import Sequence
from pathlib import Path

from fricenv.cli import _notice

#: benchmark name -> what it measures
BENCHMARKS = {
    "solvers": "accuracy and cost of every method against RK4 and SciPy",
    "sweep": "regime-map cells against an event-driven SciPy loop; full panels",
    "env": "environment step cost against Pendulum-v1; vector env; PPO's share",
    "control": "Stribeck and viscous steps against Pendulum-v1; MPC decision time",
    "compile": "cold start: first calls in fresh processes; numba compile time by kernel",
}

#: benchmark name -> the (workload, method) pairs of ``fricenv.compile_notice`` it runs
#: first (for the compile notice; the scripts may compile more later).
BENCHMARK_NEEDS: dict[str, list[tuple[str, str]]] = {
    "solvers": [("simulate", "exact"), ("simulate", "event"), ("simulate", "rk4")],
    "sweep": [("sweep", "exact")],
    "env": [("env", "exact"), ("vector_env", "exact")],
    "control": [("env", "event")],
    "compile": [],  # (each workload compiles in a child process with a cache of its own)
}


def scripts_dir() -> Path:
    """``scripts/`` of the checkout that holds this package."""
    return Path(__file__).resolve().parents[2] / "scripts"


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="benchmarks:\n" + "\n".join(
                                    f"  {k:<8} {v}" for k, v in BENCHMARKS.items()))
    p.add_argument("name", choices=list(BENCHMARKS), help="which benchmark")
    args = p.parse_args(argv[:1] or ["--help"])
    script = scripts_dir() / f"bench_{args.name}.py"
    if not script.is_file():
        p.error(f"{script} not found: the benchmarks run from a clone of the repository "
                "(pip install -e .), as they need its tests' SciPy reference")
    if not {"-h", "--help"} & set(argv[1:]):
        _notice.announce(BENCHMARK_NEEDS[args.name])
    name = f"{prog or 'fricenv bench'} {args.name}"
    saved = sys.argv
    sys.argv = [name, *argv[1:]]
    try:
        runpy.run_path(str(script), run_name="__main__")
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    finally:
        sys.argv = saved
    return 0
