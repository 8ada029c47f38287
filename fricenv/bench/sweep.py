"""Benchmark of the regime-map sweep; all ratios from one run.

1. Per-cell throughput against an event-driven SciPy ``solve_ivp`` loop
   (:mod:`fricenv.testing.scipy_reference`, written independently of the kernels) on the same cells
   (same transient + window), with the accuracy of both measured against a tight reference.
2. Wall time of one full 200 x 200 map panel (default: Fig. 8a, Coulomb, eta = 1/9) and,
   with ``--all-panels``, of all 12 panels of Figs. 8-10.
3. The regime labels of a Stribeck panel at the sweep's default tolerance against rtol 1e-9.

Usage: ``fricenv bench sweep [--threads N] [--all-panels] [--json PATH]``.
Timings depend on the machine's load; never assert on them in tests.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fricenv.bench import show_progress, stage
from fricenv.checks import check_output_file
from fricenv.layout import METHOD_EVENT, METHOD_EXACT, N_STATE, N_STATS, S_V, S_X
from fricenv.params import P_W2, OscillatorParams
from fricenv.reproduce import FULL, MAP_FIGURES, eta_name, map_grid
from fricenv.sweep import (
    SweepSettings,
    check_n_threads,
    plan_cells,
    regime_map,
    run_cells,
)

#: Cells of the comparison: (nu, u0) at the paper's defaults, one per regime family.
CELLS = [(0.5, 0.3), (0.5, 2.0), (1.5, 2.0), (0.5, 30.0), (2.0, 1.0), (0.25, 5.0)]


def _cell_setup(law: str, settings: SweepSettings) -> tuple[list, np.ndarray, np.ndarray]:
    params, spans, rows = [], [], []
    for nu, u0 in CELLS:
        p = OscillatorParams.preset(law, nu=nu, u0=u0)
        plan = plan_cells(p, np.array([nu]), settings)
        P = p.to_array()
        P[P_W2] = plan.nu_exact[0] * p.eta
        params.append(p)
        spans.append(plan.t_transient[0] + plan.n_segment[0] * plan.t_segment[0])
        rows.append(P)
    return params, np.array(spans), np.array(rows)


def _final_state(P: np.ndarray, t_end: float, method: int, rtol: float, atol: float
                 ) -> tuple[float, float]:
    from fricenv import core  # (the kernels: here, so that --help loads none)

    S = np.empty(N_STATE)
    st = np.empty(N_STATS)
    core.initial_state(P, 0.0, 0.0, S)
    core.reset_stats(st)
    core.advance(P, S, t_end, st, method, rtol, atol, 10**8, core.new_workspace())
    return S[S_X], S[S_V]


def _scipy_final(p: OscillatorParams, t_end: float, rtol: float, atol: float,
                 max_step: float) -> tuple[tuple[float, float], float]:
    from fricenv.testing.scipy_reference import reference_run

    t0 = time.perf_counter()
    run = reference_run(p, t_end, rtol=rtol, atol=atol, max_step=max_step)
    el = time.perf_counter() - t0
    x, v, _ = run.evaluate(np.array([t_end]))
    return (float(x[0]), float(v[0])), el


def _max_threads() -> int:
    """numba's thread pool size (``NUMBA_NUM_THREADS``), the default of ``--threads``."""
    from fricenv.jit import max_threads  # (here, not above: --help loads no numba)

    return max_threads()


def compare_with_scipy(law: str, ours_rtol: float, scipy_rtols: list[float], reps: int,
                       n_threads: int | None) -> dict:
    """Per-cell time of the sweep kernel and of SciPy, and both errors at the run's end."""
    settings = SweepSettings(rtol=ours_rtol, atol=ours_rtol * 1e-2)
    method = METHOD_EXACT if law == "coulomb" else METHOD_EVENT
    params, spans, rows = _cell_setup(law, settings)
    # tight reference (SciPy DOP853, rtol = atol = 1e-12, steps <= 0.05)
    ref = [_scipy_final(p, T, 1e-12, 1e-12, 0.05)[0] for p, T in zip(params, spans, strict=True)]
    ours = [_final_state(P, T, method, settings.rtol, settings.atol)
            for P, T in zip(rows, spans, strict=True)]
    err_ours = max(max(abs(a[0] - b[0]), abs(a[1] - b[1])) for a, b in zip(ours, ref,
                                                                          strict=True))
    # our throughput: the same cells through the parallel sweep kernel, many times over
    P_all = np.repeat(rows, reps, axis=0)
    plans = [plan_cells(p, np.array([p.nu]), settings) for p in params]
    tt = np.repeat([pl.t_transient[0] for pl in plans], reps)
    ts = np.repeat([pl.t_segment[0] for pl in plans], reps)
    ns = np.repeat([pl.n_segment[0] for pl in plans], reps)
    tr = np.repeat([pl.tries[0] for pl in plans], reps)
    run_cells(P_all[:len(CELLS)], tt[:len(CELLS)], ts[:len(CELLS)], ns[:len(CELLS)],
              tr[:len(CELLS)], settings, method, 1)  # compile
    res = {"law": law, "cells": CELLS, "span": spans.tolist(), "ours_rtol": ours_rtol,
           "ours_max_error": err_ours}
    for n in sorted({1, n_threads or _max_threads()}):
        t0 = time.perf_counter()
        run_cells(P_all, tt, ts, ns, tr, settings, method, n)
        res[f"ours_s_per_cell_{n}threads"] = (time.perf_counter() - t0) / P_all.shape[0]
    for rt in scipy_rtols:
        tot, err = 0.0, 0.0
        for p, T, r in zip(params, spans, ref, strict=True):
            (x, v), el = _scipy_final(p, T, rt, rt * 1e-2, 0.25)
            tot += el
            err = max(err, abs(x - r[0]), abs(v - r[1]))
        res[f"scipy_rtol{rt:g}"] = {"s_per_cell": tot / len(CELLS), "max_error": err}
    return res


def time_panel(law: str, eta: float, u_range: tuple[float, float], n_threads: int | None
               ) -> tuple[float, dict]:
    u0, nu = map_grid(u_range, FULL)
    p = OscillatorParams.preset(law, eta=eta)
    t0 = time.perf_counter()
    m = regime_map(p, u0, nu, n_threads=n_threads, progress=show_progress())
    return time.perf_counter() - t0, m.counts()


def label_agreement(n_threads: int | None) -> dict:
    u0 = np.geomspace(0.1, 1000, 24)
    nu = np.linspace(0.1, 4.0, 40)
    p = OscillatorParams.preset("stribeck", eta=0.6)
    default = SweepSettings()
    a = regime_map(p, u0, nu, settings=default, n_threads=n_threads, progress=False)
    b = regime_map(p, u0, nu, rtol=1e-9, atol=1e-11, n_threads=n_threads, progress=False)
    return {"cells": int(a.labels.size), "differ": int(np.sum(a.labels != b.labels)),
            "default_rtol": default.rtol, "elapsed_default": a.elapsed,
            "elapsed_1e-9": b.elapsed}


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog=prog, description="Regime-map cells against an event-driven SciPy loop, and "
        "the wall time of full 200 x 200 panels.",
        epilog="example:\n  fricenv bench sweep --reps 30 --skip-panel --json out/sweep.json",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--threads", type=int, default=None,
                    help="numba threads (default: all)")
    ap.add_argument("--reps", type=int, default=300,
                    help="replicas of each cell in the timed sweep (default: 300)")
    ap.add_argument("--all-panels", action="store_true", help="time all 12 panels")
    ap.add_argument("--skip-panel", action="store_true", help="skip the 200x200 panel")
    ap.add_argument("--json", type=Path, default=Path("out/bench_sweep.json"),
                    help="write the results to this file (default: out/bench_sweep.json)")
    return ap


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """Run the benchmark (it checks no bound: its numbers are ratios to read)."""
    ap = build_parser(prog)
    a = ap.parse_args(argv)
    try:
        import fricenv.testing.scipy_reference  # noqa: F401
    except ImportError as e:
        ap.error(str(e))
    if a.threads is not None:
        try:
            check_n_threads(a.threads)
        except ValueError as e:
            ap.error(f"--threads: {e}")
    if a.reps < 1:
        ap.error(f"--reps must be >= 1, got {a.reps}")
    try:  # before the benchmark, not after minutes of it
        check_output_file("--json", a.json)
    except ValueError as e:
        ap.error(str(e))
    out: dict = {"threads": a.threads or _max_threads()}

    print("== per-cell throughput vs SciPy solve_ivp (DOP853, event-driven) ==", flush=True)
    stage("timing sweep cells against SciPy (3 comparisons)")
    # Stribeck: each SciPy tolerance against ours at the loosest rtol whose end-state error
    # is no larger than SciPy's (both errors are printed), i.e. at equal or better accuracy
    for law, ours_rtol, sc in (("coulomb", 1e-10, [1e-10, 1e-8]),
                               ("stribeck", 1e-10, [1e-10]),
                               ("stribeck", 1e-9, [1e-8])):
        stage(f"cells: {law}, fricenv rtol {ours_rtol:g} against SciPy rtol "
              + ", ".join(f"{t:g}" for t in sc))
        r = compare_with_scipy(law, ours_rtol, sc, a.reps, a.threads)
        out[f"cells_{law}_rtol{ours_rtol:g}"] = r
        keys = [k for k in r if k.startswith("ours_s_per_cell")]
        for k in keys:
            print(f"{law:8s} fricenv rtol={ours_rtol:g} ({k[16:]}): {r[k] * 1e3:8.3f} ms/cell, "
                  f"max end-state error {r['ours_max_error']:.1e}")
        for rt in sc:
            s = r[f"scipy_rtol{rt:g}"]
            ratios = ", ".join(f"{s['s_per_cell'] / r[k]:.0f}x ({k[16:]})" for k in keys)
            print(f"{law:8s} SciPy rtol={rt:g}: {s['s_per_cell'] * 1e3:8.1f} ms/cell, "
                  f"max error {s['max_error']:.1e} -> fricenv is {ratios} faster", flush=True)

    stage("labels: two 24 x 40 Stribeck maps, default tolerance and rtol 1e-9")
    print("== regime labels: default tolerance vs rtol 1e-9 (Stribeck, eta = 3/5) ==")
    out["label_agreement"] = la = label_agreement(a.threads)
    print(f"{la['differ']} of {la['cells']} labels differ (rtol {la['default_rtol']:g}: "
          f"{la['elapsed_default']:.1f} s, 1e-9: {la['elapsed_1e-9']:.1f} s)", flush=True)

    panels = []
    if a.all_panels:
        panels = [(f, law, eta, r) for f, (law, ps) in MAP_FIGURES.items() for eta, r in ps]
    elif not a.skip_panel:
        law, ps = MAP_FIGURES[8]
        panels = [(8, law, ps[0][0], ps[0][1])]
    if panels:
        print("== 200 x 200 panels (wall time) ==")
        total = 0.0
        for fig, law, eta, rng in panels:
            stage(f"panel: Fig. {fig}, {law}, eta = {eta_name(eta)}")
            el, counts = time_panel(law, eta, rng, a.threads)
            total += el
            out[f"panel_fig{fig}_eta{eta_name(eta)}"] = {"seconds": el, "counts": counts}
            print(f"Fig. {fig} {law:8s} eta={eta_name(eta):5s}: {el:6.1f} s", flush=True)
        out["panels_total_s"] = total
        print(f"total {total:.1f} s for {len(panels)} panel(s)")
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(out, indent=1, default=float))
    print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
