"""Numba kernels of a sweep: one cell's run, and the parallel loop that shares cells out.

The validating, allocating wrapper is :func:`fricenv.cells.run_cells`. The cell's run and
the loop are written once (``_run_cell_with``, ``_cells_with``) and take the core's entry
kernel as their first argument; :func:`cells_kernel` builds each method's kernels from them
(``CELL_KERNELS``), so a Coulomb sweep compiles no Taylor or Rosenbrock code. The cells,
the settings they share and the outputs travel as three records (:class:`CellSpans`,
:class:`CellRun`, :class:`CellOutputs`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import prange

from . import core
from .atomic import fetch_add
from .core import Solver, partial_kernel
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


class CellSpans(NamedTuple):
    """Each cell's plant and time spans, one row or entry per cell."""

    P: np.ndarray  # (n, N_PARAMS) parameter rows, layout params.P_*
    t_trans: np.ndarray  # transient
    t_seg: np.ndarray  # one segment of the window
    n_seg: np.ndarray  # int64: segments per window
    tries: np.ndarray  # int64: windows tested at most (0: no periodicity test)


class Cell(NamedTuple):
    """One cell's spans (a row of :class:`CellSpans` but its plant)."""

    t_trans: float
    t_seg: float
    n_seg: int
    tries: int


class CellRun(NamedTuple):
    """What every cell of a call shares (the fields of ``SweepSettings`` the kernels read,
    and the method)."""

    x0: float  # start displacement
    v0: float  # start velocity
    method: int  # METHOD_EXACT or METHOD_EVENT (read by kernels that take it at run time)
    rtol: float
    atol: float
    rate: float  # switches allowed per unit time (the event cap of each span)
    m_max: int  # longest period tested
    tol: float  # strobe tolerance
    steps_tau: float  # step budget per unit time (W_MAX_STEPS_TAU)
    steps_cell: float  # step budget of the whole cell


class CellOutputs(NamedTuple):
    """Each cell's statistics (n, N_STATS), status and period (n,)."""

    stats: np.ndarray
    status: np.ndarray
    period: np.ndarray


@kernel(allocates=True)
def _event_cap(t_span: float, rate: float) -> int:
    return int(min(rate * t_span + 1000.0, 2.0e9))


@kernel(takes_kernels=True)
def _advance_in_cell(advance_ws, P: np.ndarray, S: np.ndarray, t_span: float,
                     stats: np.ndarray, run: CellRun, work: np.ndarray) -> int:
    """``advance_ws`` over ``t_span`` within what is left of the cell's step budget.

    A cell runs its transient and every segment of its windows as separate calls, each
    bounded by the workspace's per-call budget; spending that one budget over all of them
    bounds the cell as a whole (a cell of 49 calls of 1e6 steps each took 17 s), so a cell
    over its ``max_steps`` (``SweepSettings``) in all ends UNRESOLVED with
    ``STATUS_STEP_BUDGET``.
    """
    before = stats[ST_N_STEPS]
    solver = Solver(run.method, run.rtol, run.atol, _event_cap(t_span, run.rate))
    status = advance_ws(P, S, t_span, stats, solver, work)
    work[W_MAX_STEPS_CALL] -= stats[ST_N_STEPS] - before
    if status == STATUS_OK and work[W_MAX_STEPS_CALL] < 0.0:
        status = STATUS_STEP_BUDGET
    return status


@kernel(takes_kernels=True, allocates=True)
def _run_cell_with(advance_ws, P: np.ndarray, cell: Cell, run: CellRun, stats: np.ndarray,
                   work: np.ndarray) -> tuple[int, int]:
    """One cell: transient, then a window of ``cell.n_seg`` segments measured into
    ``stats``, each span advanced by ``advance_ws`` (the core's entry kernel for the cell's
    method).

    ``work``: the worker's workspace row, reset here for the cell. The caller owns it, so
    that another thread can stop a running cell by lowering its ``W_MAX_STEPS_CALL``.

    ``cell.tries`` = 0: no periodicity test. Otherwise the window is tested and, while no
    period is found but the strobe mismatch is still shrinking (:func:`_converging`),
    repeated up to ``tries - 1`` more times, each failed window becoming part of the
    transient (slowly converging orbits still lock; the stats are the last window's).
    """
    S = np.empty(N_STATE)
    core.initial_state(P, run.x0, run.v0, S)
    core.reset_stats(stats)
    # One workspace for the whole cell, every cache empty (NaN keys never match); the maps
    # never read the (v - V)^2 integral. The transient's stats are dropped, so it skips the
    # extrema too: locating them holds the closed form to short scan steps (1.4-2.2 times
    # the transient's cost on Coulomb cells).
    work[:] = np.nan
    work[W_SKIP_EXTREMA] = 1.0
    work[W_SKIP_VR2] = 1.0
    work[W_MAX_STEPS_TAU] = run.steps_tau
    work[W_MAX_STEPS_CALL] = run.steps_cell
    status = STATUS_OK
    if cell.t_trans > 0.0:
        status = _advance_in_cell(advance_ws, P, S, cell.t_trans, stats, run, work)
    work[W_SKIP_EXTREMA] = 0.0
    n_seg = cell.n_seg
    xs = np.empty(n_seg)
    vs = np.empty(n_seg)
    period = 0
    for _ in range(max(cell.tries, 1)):
        core.reset_stats(stats)
        k = 0
        while status == STATUS_OK and k < n_seg:
            status = _advance_in_cell(advance_ws, P, S, cell.t_seg, stats, run, work)
            xs[k] = S[S_X]
            vs[k] = S[S_V]
            k += 1
        if status != STATUS_OK or cell.tries == 0:
            break
        period = _strobe_period(xs, vs, run.m_max, run.tol)
        if period > 0 or not _converging(xs, vs, run.m_max):
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


@kernel(takes_kernels=True, allocates=True)
def _cells_with(run_cell, spans: CellSpans, run: CellRun, out: CellOutputs,
                works: np.ndarray, next_cell: np.ndarray) -> None:
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
    n = spans.P.shape[0]
    # (the outputs out of their record before the loop: numba's parallel passes drop a
    # write inside a prange body through a record's field)
    out_stats, out_status, out_period = out.stats, out.status, out.period
    for w in prange(works.shape[0]):
        work = works[w]
        c = fetch_add(next_cell, 0, 1)
        while c < n:
            P = spans.P[c].copy()
            stats = np.empty(N_STATS)
            cell = Cell(spans.t_trans[c], spans.t_seg[c], spans.n_seg[c], spans.tries[c])
            st, per = run_cell(P, cell, run, stats, work)
            out_stats[c, :] = stats
            out_status[c] = st
            out_period[c] = per
            c = fetch_add(next_cell, 0, 1)


def cells_kernel(advance_ws: Any, method: str) -> Any:
    """The parallel cell kernel ``(spans, run, out, works, next_cell)`` that advances every
    cell by the core's entry kernel ``advance_ws``: ``_cells_with`` over a cell kernel of
    its own (``_run_cell_with``), which is compiled once and called per cell. ``method``
    names the kernels (``_run_cell_exact``, ``_cells_kernel_exact``)."""
    run_cell = partial_kernel(_run_cell_with, advance_ws, f"_run_cell_{method}",
                              allocates=True)
    return partial_kernel(_cells_with, run_cell, f"_cells_kernel_{method}", parallel=True,
                          allocates=True, nogil=True)


#: The parallel cell kernel of each method (the run's method is still passed to it); the
#: closed form's needs every plant conditioned.
CELL_KERNELS = {METHOD_EXACT: cells_kernel(core.advance_exact_ws, "exact"),
                METHOD_EVENT: cells_kernel(core.advance_event_ws, "event")}
