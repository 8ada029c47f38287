"""Numba kernels of a sweep: one cell's run, and the parallel loop that shares cells out.

The validating, allocating wrapper is :func:`fricenv.cells.run_cells`. The cell's run and
the loop are written once (``_run_cell_with``, ``_cells_with``) and take the core's entry
kernel as their first argument; each method has its own compiled kernels
(``CELL_KERNELS``), so a Coulomb sweep compiles no Taylor or Rosenbrock code.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from . import core
from .atomic import fetch_add
from .core.workspace import W_MAX_STEPS_CALL, W_MAX_STEPS_TAU, W_SKIP_EXTREMA, W_SKIP_VR2
from .jit import kernel
from .layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    N_STATE,
    N_STATS,
    S_V,
    S_X,
    ST_N_STEPS,
    ST_VR2_INT,
    STATUS_OK,
    STATUS_STEP_BUDGET,
)
from .regimes import _strobe_period


@kernel(allocates=True)
def _event_cap(t_span: float, rate: float) -> int:
    return int(min(rate * t_span + 1000.0, 2.0e9))


@kernel(takes_kernels=True)
def _advance_in_cell(advance_ws, P: np.ndarray, S: np.ndarray, t_span: float,
                     stats: np.ndarray, method: int, rtol: float, atol: float,
                     max_events: int, work: np.ndarray) -> int:
    """``advance_ws`` within what is left of the cell's step budget.

    A cell runs its transient and every segment of its windows as separate calls, each
    bounded by the workspace's per-call budget; spending that one budget over all of them
    bounds the cell as a whole (a cell of 49 calls of 1e6 steps each took 17 s), so a cell
    over its ``max_steps`` (``SweepSettings``) in all ends UNRESOLVED with
    ``STATUS_STEP_BUDGET``.
    """
    before = stats[ST_N_STEPS]
    status = advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, work)
    work[W_MAX_STEPS_CALL] -= stats[ST_N_STEPS] - before
    if status == STATUS_OK and work[W_MAX_STEPS_CALL] < 0.0:
        status = STATUS_STEP_BUDGET
    return status


@kernel(takes_kernels=True, allocates=True)
def _run_cell_with(advance_ws, P: np.ndarray, x0: float, v0: float, t_trans: float,
                   t_seg: float, n_seg: int, tries: int, method: int, rtol: float, atol: float,
                   rate: float, m_max: int, tol: float, steps_tau: float, steps_cell: float,
                   stats: np.ndarray, work: np.ndarray) -> tuple[int, int]:
    """One cell: transient, then a window of ``n_seg`` segments measured into ``stats``,
    each span advanced by ``advance_ws`` (the core's entry kernel for the cell's method).

    ``work``: the worker's workspace row, reset here for the cell. The caller owns it, so
    that another thread can stop a running cell by lowering its ``W_MAX_STEPS_CALL``.

    ``tries`` = 0: no periodicity test. Otherwise the window is tested and, while no period
    is found but the strobe mismatch is still shrinking (:func:`_converging`), repeated up
    to ``tries - 1`` more times, each failed window becoming part of the transient (slowly
    converging orbits still lock; the stats are the last window's).
    """
    S = np.empty(N_STATE)
    core.initial_state(P, x0, v0, S)
    core.reset_stats(stats)
    # One workspace for the whole cell, every cache empty (NaN keys never match); the maps
    # never read the (v - V)^2 integral. The transient's stats are dropped, so it skips the
    # extrema too: locating them holds the closed form to short scan steps (1.4-2.2 times
    # the transient's cost on Coulomb cells).
    work[:] = np.nan
    work[W_SKIP_EXTREMA] = 1.0
    work[W_SKIP_VR2] = 1.0
    work[W_MAX_STEPS_TAU] = steps_tau
    work[W_MAX_STEPS_CALL] = steps_cell
    status = STATUS_OK
    if t_trans > 0.0:
        status = _advance_in_cell(advance_ws, P, S, t_trans, stats, method, rtol, atol,
                                  _event_cap(t_trans, rate), work)
    work[W_SKIP_EXTREMA] = 0.0
    xs = np.empty(n_seg)
    vs = np.empty(n_seg)
    period = 0
    for _ in range(max(tries, 1)):
        core.reset_stats(stats)
        k = 0
        while status == STATUS_OK and k < n_seg:
            status = _advance_in_cell(advance_ws, P, S, t_seg, stats, method, rtol, atol,
                                      _event_cap(t_seg, rate), work)
            xs[k] = S[S_X]
            vs[k] = S[S_V]
            k += 1
        if status != STATUS_OK or tries == 0:
            break
        period = _strobe_period(xs, vs, m_max, tol)
        if period > 0 or not _converging(xs, vs, m_max):
            break
    stats[ST_VR2_INT] = np.nan  # skipped (the maps never read it): not a measured 0
    return status, period


@kernel(allocates=True)
def _converging(xs: np.ndarray, vs: np.ndarray, m_max: int) -> bool:
    """True if, for some candidate period m, the strobe mismatch |z_k - z_{k-m}| shrinks by
    half or more from the first to the second half of the window: an orbit still
    converging (worth another window), unlike a quasi-periodic or chaotic one."""
    n = xs.shape[0]
    for m in range(1, m_max + 1):
        if n - m < 4:
            break
        half = m + (n - m) // 2
        r1 = 0.0
        r2 = 0.0
        for k in range(m, n):
            d = max(abs(xs[k] - xs[k - m]), abs(vs[k] - vs[k - m]))
            if k < half:
                r1 = max(r1, d)
            else:
                r2 = max(r2, d)
        if r2 < 0.5 * r1:
            return True
    return False


@kernel(allocates=True)
def _run_cell_exact(P, x0, v0, t_trans, t_seg, n_seg, tries, method, rtol, atol, rate, m_max,
                    tol, steps_tau, steps_cell, stats, work):
    """``_run_cell_with`` by the closed form (the cell's plant must be conditioned)."""
    return _run_cell_with(core.advance_exact_ws, P, x0, v0, t_trans, t_seg, n_seg, tries,
                          method, rtol, atol, rate, m_max, tol, steps_tau, steps_cell, stats,
                          work)


@kernel(allocates=True)
def _run_cell_event(P, x0, v0, t_trans, t_seg, n_seg, tries, method, rtol, atol, rate, m_max,
                    tol, steps_tau, steps_cell, stats, work):
    """``_run_cell_with`` by the event method."""
    return _run_cell_with(core.advance_event_ws, P, x0, v0, t_trans, t_seg, n_seg, tries,
                          method, rtol, atol, rate, m_max, tol, steps_tau, steps_cell, stats,
                          work)


@kernel(takes_kernels=True, allocates=True)
def _cells_with(run_cell, P_cells: np.ndarray, t_trans: np.ndarray, t_seg: np.ndarray,
                n_seg: np.ndarray, tries: np.ndarray, x0: float, v0: float, method: int,
                rtol: float, atol: float, rate: float, m_max: int, tol: float,
                steps_tau: float, steps_cell: float, out_stats: np.ndarray, out_status: np.ndarray,
                out_period: np.ndarray, works: np.ndarray, next_cell: np.ndarray) -> None:
    """Run the cells by ``run_cell`` on ``works.shape[0]`` workers (one ``prange``
    iteration each, with its own workspace row ``works[w]``).

    Cells differ in cost by orders of magnitude (a stiff or slowly locking cell runs long
    transients), so rather than take a fixed share, each worker claims the next cell from
    the counter ``next_cell[0]`` (bumped atomically) as soon as it is free. To stop the
    run from another thread, set ``next_cell[0]`` to at least the number of cells (no cell
    is claimed after that) and each row's ``W_MAX_STEPS_CALL`` below 0 (the running cells
    end within ``BUDGET_CHECK_STEPS`` steps, with ``STATUS_STEP_BUDGET``); cells never
    claimed keep the status their outputs started with.
    """
    n = P_cells.shape[0]
    for w in prange(works.shape[0]):
        work = works[w]
        c = fetch_add(next_cell, 0, 1)
        while c < n:
            P = P_cells[c].copy()
            stats = np.empty(N_STATS)
            st, per = run_cell(P, x0, v0, t_trans[c], t_seg[c], n_seg[c], tries[c], method,
                               rtol, atol, rate, m_max, tol, steps_tau, steps_cell, stats,
                               work)
            out_stats[c, :] = stats
            out_status[c] = st
            out_period[c] = per
            c = fetch_add(next_cell, 0, 1)


@kernel(parallel=True, allocates=True, nogil=True)
def _cells_kernel_exact(P_cells, t_trans, t_seg, n_seg, tries, x0, v0, method, rtol, atol,
                        rate, m_max, tol, steps_tau, steps_cell, out_stats, out_status,
                        out_period, works, next_cell):
    """``_cells_with`` by the closed form (every plant conditioned)."""
    _cells_with(_run_cell_exact, P_cells, t_trans, t_seg, n_seg, tries, x0, v0, method, rtol,
                atol, rate, m_max, tol, steps_tau, steps_cell, out_stats, out_status,
                out_period, works, next_cell)


@kernel(parallel=True, allocates=True, nogil=True)
def _cells_kernel_event(P_cells, t_trans, t_seg, n_seg, tries, x0, v0, method, rtol, atol,
                        rate, m_max, tol, steps_tau, steps_cell, out_stats, out_status,
                        out_period, works, next_cell):
    """``_cells_with`` by the event method."""
    _cells_with(_run_cell_event, P_cells, t_trans, t_seg, n_seg, tries, x0, v0, method, rtol,
                atol, rate, m_max, tol, steps_tau, steps_cell, out_stats, out_status,
                out_period, works, next_cell)


#: The parallel cell kernel of each method (the run's method is still passed to it).
CELL_KERNELS = {METHOD_EXACT: _cells_kernel_exact, METHOD_EVENT: _cells_kernel_event}
