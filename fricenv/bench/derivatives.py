"""Benchmark the forward sensitivities: the cost of a run with ``wrt`` against the same
run without, and their accuracy against central differences; all ratios from one run.

For each law (Coulomb, Stribeck, exponential) on a plant that sticks, slips and reverses,
a warm ``simulate(..., method="event")`` over ``--span`` is timed with k = 1, 2 and 4
parameters in ``wrt`` and without, in alternating rounds (best of each). The bounds checked:

1. a run with k parameters costs at most (1 + k) times the plain run;
2. with k = 4, at most 3.5 times;
3. every derivative agrees with central differences of the plain simulator (h = 1e-6,
   rtol 1e-12) within 1e-6 relative, wherever the switching sequence is the same at +-h.

Usage: ``fricenv bench derivatives [--span T] [--rounds N] [--json PATH] [--report-only]``.
Timings depend on the machine's load; tests never assert on them.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence

import numpy as np

from fricenv.bench import REPORT_ONLY_HELP, stage, verdict
from fricenv.checks import check_output_file
from fricenv.params import OscillatorParams
from fricenv.simulate import OscillatorState, simulate

#: Plants and the parameters differentiated by (the first k are taken).
PLANTS: dict[str, tuple[OscillatorParams, tuple[str, ...]]] = {
    "coulomb": (OscillatorParams(u0=4.0, nu=1.7), ("xfk", "xfs", "lam", "u0")),
    "stribeck": (OscillatorParams.preset("stribeck", u0=2.0, nu=0.5),
                 ("b1", "b3", "xfs", "lam")),
    "exponential": (OscillatorParams.preset("exponential", u0=4.0, nu=1.7),
                    ("vs", "cv", "xfs", "lam")),
}
KS = (1, 2, 4)
START = (0.3, 1.4)


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog=prog, description="Time runs with derivatives (wrt=) against the same runs "
        "without, side by side, and check their derivatives against central differences.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  fricenv bench derivatives --span 500 --rounds 3")
    ap.add_argument("--span", type=float, default=2000.0,
                    help="length of each run (default: %(default)s)")
    ap.add_argument("--rounds", type=int, default=7,
                    help="alternating timing rounds (default: %(default)s)")
    ap.add_argument("--json", default=None, help="also write the numbers to this file")
    ap.add_argument("--report-only", action="store_true", help=REPORT_ONLY_HELP)
    return ap


def _best_times(calls: dict[str, Callable[[], object]], rounds: int) -> dict[str, float]:
    """Each call's best wall time over ``rounds`` rounds that alternate between them."""
    best = dict.fromkeys(calls, np.inf)
    for _ in range(rounds):
        for name, call in calls.items():
            t0 = time.perf_counter()
            call()
            best[name] = min(best[name], time.perf_counter() - t0)
    return best


def cost(law: str, span: float, rounds: int) -> dict[str, float]:
    """Warm wall time of the plain run and of runs with k = 1, 2, 4 parameters."""
    p, names = PLANTS[law]
    state = OscillatorState.start(p, *START)

    def run(k: int) -> Callable[[], object]:
        wrt = names[:k] if k else None
        return lambda: simulate(p, span, state=state, method="event", dt_out=span / 100,
                                wrt=wrt)

    calls = {f"k={k}": run(k) for k in (0, *KS)}
    for call in calls.values():  # compile, and load the caches
        call()
    return _best_times(calls, rounds)


def accuracy(law: str) -> dict[str, float]:
    """Largest relative difference of dx/dp from central differences, per parameter."""
    p, names = PLANTS[law]
    state = OscillatorState.start(p, *START)
    tr = simulate(p, 30.0, state=state, wrt=names, rtol=1e-12)
    assert tr.dx_dp is not None
    out = {}
    h = 1e-6
    for j, name in enumerate(names):
        a, b = (simulate(p.replace(**{name: getattr(p, name) + s * h}), 30.0, state=state,
                         method="event", rtol=1e-12) for s in (1.0, -1.0))
        if a.event_kind.shape != b.event_kind.shape or np.any(a.event_kind != b.event_kind):
            continue
        fd = (a.x - b.x) / (2 * h)
        out[name] = float(np.max(np.abs(tr.dx_dp[:, j] - fd)) / np.max(np.abs(fd)))
    return out


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    ap = build_parser(prog)
    a = ap.parse_args(argv)
    if not a.span > 0.0 or a.rounds < 1:
        ap.error(f"--span must be > 0 and --rounds >= 1, got {a.span}, {a.rounds}")
    try:
        if a.json:
            check_output_file("--json", a.json)
    except ValueError as e:
        ap.error(str(e))
    failures: list[str] = []
    result: dict = {}
    print(f"== cost of a warm run with k parameters, over {a.span:g} units, best of "
          f"{a.rounds} alternating rounds ==")
    print(f"{'law':<12} {'plain':>10} " + " ".join(f"{'k=' + str(k):>14}" for k in KS))
    for law in PLANTS:
        stage(f"timing {law}")
        t = cost(law, a.span, a.rounds)
        ratios = {k: t[f"k={k}"] / t["k=0"] for k in KS}
        result[law] = {"seconds": t, "ratios": {str(k): r for k, r in ratios.items()}}
        print(f"{law:<12} {t['k=0'] * 1e3:8.2f}ms " + " ".join(
            f"{t[f'k={k}'] * 1e3:7.2f}ms {ratios[k]:4.2f}x" for k in KS))
        for k in KS:
            if ratios[k] > 1 + k:
                failures.append(f"bound 1 (k = {k}: at most {1 + k}x), {law}: "
                                f"measured {ratios[k]:.2f}x")
        if ratios[4] > 3.5:
            failures.append(f"bound 2 (k = 4: at most 3.5x), {law}: measured {ratios[4]:.2f}x")
    print("== accuracy: max |dx/dp - central difference| / max |central difference| ==")
    for law in PLANTS:
        stage(f"differences for {law}")
        err = accuracy(law)
        result[law]["accuracy"] = err
        print(f"{law:<12} " + "  ".join(f"{n} {e:.1e}" for n, e in err.items()))
        failures += [f"bound 3 (at most 1e-6), {law} {n}: measured {e:.2e}"
                     for n, e in err.items() if e > 1e-6]
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)
    return verdict(failures, a.report_only)
