"""Work-precision benchmark of the solvers on the paper's cases.

Usage: ``fricenv bench solvers [--quick] [--out DIR]`` (default DIR: out/bench).

Cases: the Coulomb time histories of Figs. 4-7 and one Stribeck case, from rest, tau in
[0, 200], output every 0.1. For each (case, method) the max |x error| on the output grid
and the best wall time over repeats (after a warm-up call, so numba compilation is not
counted) are measured, the time also as a ratio to the paper's RK4 at dt = 0.04.

References: Coulomb cases use ``method="exact"``; the "exact" row itself is scored
against SciPy DOP853 at rtol = atol = 1e-13 (otherwise it would be compared with itself).
The Stribeck case uses ``method="event"`` at rtol = 1e-13, cross-checked against the same
SciPy solution (:mod:`fricenv.testing.scipy_reference`). SciPy is optional: without it the
SciPy rows and cross-checks are skipped.

The bounds checked (:data:`BOUNDS`): for each method family, some setting reaches the
error bound at no more than the time bound, relative to RK4 at dt = 0.04, on every case.
The exit status is 1 when a bound fails; the verdict names each failed bound, the value
measured and the machine's load, and ``--report-only`` reports them with status 0.
"""

from __future__ import annotations

import argparse
import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

import fricenv
from fricenv.bench import REPORT_ONLY_HELP, stage, verdict
from fricenv.checks import check_output_dir
from fricenv.params import PAPER_CASES, OscillatorParams

T_END = 200.0
DT_OUT = 0.1
C = OscillatorParams.preset
CASES: dict[str, OscillatorParams] = {
    **{f"fig{name}": C("coulomb", **kw) for name, kw in PAPER_CASES.items()},
    "stribeck": C("stribeck", eta=0.6, nu=0.1, u0=1.15),
}
BOUNDS = {"exact": (1e-10, 0.5), "event": (1e-8, 1.0)}  # (max error, max time ratio)


def tanh_rk4(params: OscillatorParams, t_end: float, dt: float = 0.01,
             eps: float = 1e-3) -> np.ndarray:
    """x on the output grid of the tanh-smoothed RK4 baseline."""
    stride = int(round(DT_OUT / dt))
    if abs(stride * dt - DT_OUT) > 1e-12:
        raise ValueError(f"dt = {dt} must divide dt_out = {DT_OUT}")
    n_out = int(round(t_end / DT_OUT)) + 1
    from fricenv.bench._tanh_rk4 import _tanh_rk4  # (numba: here, not at --help)

    p = np.array([params.lam, params.V, params.xfk, params.b1, params.b3, params.amp1,
                  params.amp2, params.omega1, params.omega2])
    return _tanh_rk4(p, 0.0, 0.0, dt, stride, n_out, eps)[0]


# ----------------------------------------------------------------------------------------
def _load_scipy_reference() -> ModuleType | None:
    """:mod:`fricenv.testing.scipy_reference`, or None (with a note) without SciPy."""
    try:
        from fricenv.testing import scipy_reference
    except ImportError as e:
        print(f"note: {e}; SciPy rows and cross-checks are skipped")
        return None
    return scipy_reference


@dataclass
class Row:
    case: str
    method: str
    err: float
    seconds: float
    ratio: float = math.nan
    steps: int | None = None


def best_time(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    """Best wall time of ``repeats`` calls after one warm-up call; returns (s, result)."""
    out = fn()
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


#: Tolerances of the event rows (rtol = atol): decades plus the setting that lands near 1e-8.
EVENT_TOLS = (1e-6, 1e-8, 3e-9, 1e-9, 1e-10, 1e-12)


def _scipy_x(sref: ModuleType, params: OscillatorParams, grid: np.ndarray,
             rtol: float) -> np.ndarray:
    """x of the SciPy reference on ``grid`` at rtol = atol = ``rtol``."""
    return sref.reference_solution(params, T_END, t_eval=grid, rtol=rtol, atol=rtol)[1]


def methods_for(params: OscillatorParams, sref: ModuleType | None
                ) -> list[tuple[str, Callable[[], object]]]:
    """(label, thunk returning a Trajectory or an x array) for every method of a case."""
    sim = functools.partial(fricenv.simulate, params, T_END, dt_out=DT_OUT)
    ms: list[tuple[str, Callable[[], object]]] = []
    if params.is_coulomb:
        ms.append(("exact", functools.partial(sim, method="exact")))
    for tol in EVENT_TOLS:
        ms.append((f"event tol={tol:.0e}",
                   functools.partial(sim, method="event", rtol=tol, atol=tol)))
    for dt in (0.04, 0.01, 0.0025):
        ms.append((f"rk4 dt={dt}", functools.partial(sim, method="rk4", dt=dt)))
    ms.append(("tanh-rk4 eps=1e-3 dt=0.01",
               functools.partial(tanh_rk4, params, T_END, 0.01, 1e-3)))
    if sref is not None:
        grid = np.linspace(0.0, T_END, int(round(T_END / DT_OUT)) + 1)
        for rtol in (1e-8, 1e-12):
            ms.append((f"scipy DOP853 rtol={rtol:.0e}",
                       functools.partial(_scipy_x, sref, params, grid, rtol)))
    return ms


def _x_of(out: object) -> np.ndarray:
    return np.asarray(out.x if hasattr(out, "x") else out)


def run(quick: bool, out_dir: Path, cases: Sequence[str] = tuple(CASES)
        ) -> tuple[list[Row], list[str]]:
    """Time and score every method on the ``cases``, then report; (rows, the bounds that
    fail)."""
    sref = _load_scipy_reference()
    repeats = 2 if quick else 7
    slow_repeats = 1 if quick else 2
    grid = np.linspace(0.0, T_END, int(round(T_END / DT_OUT)) + 1)
    rows: list[Row] = []
    notes: list[str] = []
    for case in cases:
        params = CASES[case]
        stage(f"case {case}: references, then {len(methods_for(params, sref))} methods")
        sp_x = None
        if sref is not None:
            sp_x = sref.reference_solution(params, T_END, t_eval=grid, rtol=1e-13,
                                           atol=1e-13)[1]
        if params.is_coulomb:
            ref = fricenv.simulate(params, T_END, dt_out=DT_OUT, method="exact")
            label = "exact"
        else:
            ref = fricenv.simulate(params, T_END, dt_out=DT_OUT, method="event", rtol=1e-13,
                                   atol=1e-15)
            label = "event rtol=1e-13"
        assert np.allclose(ref.t, grid, rtol=0, atol=1e-9), "unexpected output grid"
        if sp_x is not None:
            d = float(np.abs(ref.x - sp_x).max())
            notes.append(f"{case}: reference ({label}) vs SciPy DOP853 1e-13: max|dx| = {d:.1e}")
        t_rk = None
        for name, thunk in methods_for(params, sref):
            reps = slow_repeats if name.startswith("scipy") else repeats
            secs, out = best_time(thunk, reps)
            x = _x_of(out)
            target = sp_x if (name == "exact" and sp_x is not None) else ref.x
            err = float(np.abs(x - target).max())
            steps = getattr(out, "n_steps", None)
            rows.append(Row(case, name, err, secs, steps=steps))
            if name == "rk4 dt=0.04":
                t_rk = secs
            print(f"  {case:9s} {name:28s} err {err:9.2e}  {secs * 1e3:9.3f} ms", flush=True)
        assert t_rk is not None, "every case has the rk4 dt=0.04 row"
        for r in rows:
            if r.case == case:
                r.ratio = r.seconds / t_rk
    return rows, report(rows, notes, out_dir)


def _uniform_setting(rows: list[Row], fam: str, emax: float, rmax: float) -> str:
    """The cheapest single setting of a method family that meets the error on every case."""
    best = None
    fam_cases = {r.case for r in rows if r.method.split()[0] == fam}  # where it applies
    for m in dict.fromkeys(r.method for r in rows if r.method.split()[0] == fam):
        rs = [r for r in rows if r.method == m]
        if {r.case for r in rs} == fam_cases and all(r.err <= emax for r in rs):
            worst = max(r.ratio for r in rs)
            if best is None or worst < best[1]:
                best = (m, worst, max(r.err for r in rs))
    if best is None:
        return f"- {fam}: no single setting reaches error <= {emax:.0e} on every case"
    verdict = "HOLDS" if best[1] <= rmax else "FAILS"
    return (f"- {fam}, one setting for all cases: `{best[0]}` worst error {best[2]:.1e}, "
            f"worst time {best[1]:.2f}x rk4(0.04): **{verdict}**")


def _targets(rows: list[Row]) -> tuple[list[str], list[str]]:
    """The bound lines of the report, and one line per bound that fails, naming it, the case
    and what was measured (the uniform-setting lines are information: a family may need
    different settings on different cases)."""
    lines = [_uniform_setting(rows, fam, emax, rmax) for fam, (emax, rmax) in BOUNDS.items()]
    failures = []
    for fam, (emax, rmax) in BOUNDS.items():
        ok_all = True
        parts = []
        for case in dict.fromkeys(r.case for r in rows):
            cand = [r for r in rows if r.case == case and r.method.split()[0] == fam]
            if not cand:
                continue
            good = [r for r in cand if r.err <= emax]
            best = min(good, key=lambda r: r.ratio) if good else None
            ok = best is not None and best.ratio <= rmax
            ok_all &= ok
            if not ok:
                failures.append(
                    f"{fam}: error <= {emax:.0e} at <= {rmax}x rk4(0.04) time, case {case}: "
                    + (f"measured {best.ratio:.2f}x ({best.method}, error {best.err:.1e})"
                       if best else f"no setting reaches the error (best "
                       f"{min(r.err for r in cand):.1e})"))
            parts.append(f"{case}: " + (f"{best.method} err {best.err:.1e} at "
                                        f"{best.ratio:.2f}x" if best else "no setting") +
                         ("" if ok else " FAIL"))
        lines.append(f"- {fam}: error <= {emax:.0e} at <= {rmax}x rk4(0.04) time on every "
                     f"case: **{'HOLDS' if ok_all else 'FAILS'}** ({'; '.join(parts)})")
    return lines, failures


def report(rows: list[Row], notes: list[str], out_dir: Path) -> list[str]:
    """Print and write the tables, the bounds and the plot; the bounds that fail (one line
    each, see :func:`fricenv.bench.verdict`)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    md = ["| case | method | max abs x error | time [ms] | time / rk4(0.04) | steps |",
          "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        md.append(f"| {r.case} | {r.method} | {r.err:.2e} | {r.seconds * 1e3:.3f} | "
                  f"{r.ratio:.2f} | {'' if r.steps is None else r.steps} |")
    summary = ["", "Per method: worst error over cases, geometric-mean time ratio", "",
               "| method | worst error | geo-mean time / rk4(0.04) | cases |",
               "|---|---:|---:|---:|"]
    for m in dict.fromkeys(r.method for r in rows):
        rs = [r for r in rows if r.method == m]
        gm = math.exp(sum(math.log(r.ratio) for r in rs) / len(rs))
        summary.append(f"| {m} | {max(r.err for r in rs):.2e} | {gm:.3f} | {len(rs)} |")
    bound_lines, failures = _targets(rows)
    tail = ["", "Bounds checked (each method family, with the best of its settings per "
            "case, reaches the error bound within the time bound, relative to RK4 at "
            "dt = 0.04):", "", *bound_lines, "", "Notes:", "",
            "- Coulomb reference: `exact`; its own row is scored against SciPy DOP853 "
            "(rtol = atol = 1e-13). Stribeck reference: `event` at rtol = 1e-13.",
            "- event rows use rtol = atol = tol; times are best of repeats after a warm-up.",
            "- SciPy rows are the reference of fricenv.testing.scipy_reference: DOP853 with "
            "max_step = 0.1, so their cost and error barely depend on rtol.",
            *[f"- {n}" for n in notes]]
    text = "\n".join(md + summary + tail) + "\n"
    print()
    print(text)
    (out_dir / "bench_solvers.md").write_text(text)
    plot(rows, out_dir / "bench_solvers.png")
    print(f"wrote {out_dir / 'bench_solvers.md'} and {out_dir / 'bench_solvers.png'}")
    return failures


def plot(rows: list[Row], path: Path) -> None:
    """Error against wall time, one colour per method family and one marker per case."""
    from fricenv import plotting

    fam_color = {"exact": "C3", "event": "C0", "rk4": "C1", "tanh-rk4": "C2", "scipy": "C4"}
    markers = dict(zip(CASES, "os^vDP*", strict=False))
    fig = plotting.ShowableFigure(figsize=(8, 5.5), layout="constrained")
    ax = fig.add_subplot()
    for r in rows:
        fam = r.method.split()[0]
        ax.loglog(r.seconds * 1e3, max(r.err, 1e-16), markers[r.case],
                  color=fam_color.get(fam, "k"), alpha=0.8, ms=6)
    for fam, c in fam_color.items():
        ax.plot([], [], "s", color=c, label=fam)
    for case, mk in markers.items():
        ax.plot([], [], mk, color="gray", label=case)
    ax.set_xlabel("wall time per run (ms), τ in [0, 200]")
    ax.set_ylabel("max |x error| on the output grid (dimensionless)")
    ax.set_title("Work-precision: fricenv solvers vs baselines")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, ncol=2, title="colour: method; marker: case")
    plotting.save(fig, path, dpi=120)


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog=prog, description="Work-precision of every solver on the paper's cases, "
        "against RK4 and SciPy.",
        epilog="example:\n  fricenv bench solvers --quick --cases fig4a stribeck",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer timing repeats")
    ap.add_argument("--out", type=Path, default=Path("out") / "bench",
                    help="output folder of the table and plot (default: out/bench)")
    ap.add_argument("--cases", nargs="+", choices=list(CASES), default=list(CASES),
                    metavar="CASE", help="the cases to run, of " + ", ".join(CASES)
                    + " (default: all)")
    ap.add_argument("--report-only", action="store_true", help=REPORT_ONLY_HELP)
    return ap


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """Run the benchmark; the exit status is 1 when a bound fails."""
    ap = build_parser(prog)
    args = ap.parse_args(argv)
    try:  # before the benchmark, not after minutes of it
        check_output_dir("--out", args.out)
    except ValueError as e:
        ap.error(str(e))
    _, failures = run(args.quick, args.out, args.cases)
    return verdict(failures, args.report_only)


if __name__ == "__main__":
    raise SystemExit(main())
