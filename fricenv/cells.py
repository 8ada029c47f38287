"""Cells of a sweep: their settings, time spans, the checked parallel run and the labels.

A cell is one independent run of the stats-only core from a given state: a transient, then a
measurement window of stroboscopic segments (see :mod:`fricenv.sweep` for the formulas).
:func:`measure_cells` is the one path from parameters to labels that regime maps,
``cell_statistics`` and atlases share: parameter rows and time spans
(:func:`cell_inputs`, :func:`plan_cells`), the parallel run (:func:`run_cells`, which
validates and allocates; its numba kernels are in :mod:`fricenv.cell_kernels`) and the
labels (:func:`fricenv.regimes.classify`). A cell depends only on its own values, so every
caller gets the same bits for the same cell.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, fields
from typing import NamedTuple

import numba
import numpy as np

from . import calls
from .cell_kernels import CELL_KERNELS, CellOutputs, CellRun, CellSpans
from .checks import (
    check_bool,
    check_bounded_real,
    check_finite_real,
    check_int,
    check_rtol,
    got,
    real_array,
)
from .core import conditioned_rows
from .core.constants import MAX_STEPS_PER_CALL, MAX_STEPS_PER_TAU
from .core.workspace import N_WORK, W_MAX_STEPS_CALL
from .divergence import diverged
from .friction import LAWS, OWNER, closed_form_rows, law_of_code
from .jit import parallel_section
from .layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    METHODS,
    N_STATS,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_SLIP,
    ST_N_STICK,
    ST_STICK_TIME,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_STEP_BUDGET,
)
from .params import (
    N_PARAMS,
    P_LAM,
    P_LAW,
    P_U1,
    P_U2,
    P_V,
    P_W1,
    P_W2,
    P_XFK,
    P_XFS,
    PARAM_LIMIT,
    OscillatorParams,
)
from .regimes import classify, exact_rationals, rational_denominators
from .simulate import check_scan_steps

#: Most stroboscopic samples a cell keeps (two float64 each): ample for any sensible window
#: (about 40 at eta = 7/3, 1600 at eta = 100), far below what would exhaust memory.
MAX_SEGMENTS = 1_000_000
#: Largest tested denominator / candidate period (the map stores both as int16, and a
#: common period of 1000 forcing periods, sampled n_strobe times, already runs for hours).
MAX_PERIOD = 1000
#: Most repeated windows of a slowly locking cell (each is a full window).
MAX_LOCK_EXTENSIONS = 100
#: A cell that the kernel never wrote (its outputs start so): not a :mod:`layout` status.
STATUS_NOT_RUN = -1
#: Label of a cell that has not been computed yet (not a :class:`~fricenv.regimes.Regime`).
NOT_COMPUTED = -1

#: The integer-valued fields of :class:`SweepSettings` and their largest values: beyond
#: them the int64 kernels' arguments or the segment counts would overflow.
_INT_SETTINGS = {"q_max": MAX_PERIOD, "m_max": MAX_PERIOD,
                 "lock_extensions": MAX_LOCK_EXTENSIONS, "n_strobe": MAX_SEGMENTS}


@dataclass(frozen=True)
class SweepSettings:
    """How each cell is run and measured (see the module docstring for the formulas).

    ``x0, v0``: initial state, at rest by default (so the block starts slipping backwards
    relative to the belt). ``method``: ``"auto"`` (closed form for Coulomb, event-driven
    otherwise), ``"exact"`` or ``"event"``. ``rtol, atol``: tolerances of the event-driven
    integrator (the closed form ignores them); 1e-6 / 1e-8 gave labels identical to 1e-9 on
    every cell checked (scripts/bench_sweep.py repeats the check) at half the cost.
    ``max_event_rate``: events allowed per unit time before a cell is declared UNRESOLVED
    (chattering); ``max_steps_per_tau, max_steps``: the cell's step budget (as in
    :func:`fricenv.run_stats`, ``max_steps`` spent over the transient and all windows
    together; a cell past it is UNRESOLVED with ``STATUS_STEP_BUDGET``); ``q_max, m_max,
    n_strobe, strobe_tol, lock_extensions``: periodicity test. ``lyapunov``: also measure
    each cell's largest Lyapunov exponent over its window
    (:func:`fricenv.stability.lyapunov_of_cells`).
    ``x0, v0`` lie within
    ``PARAM_LIMIT`` like every parameter; ``q_max`` and ``m_max`` are at most
    ``MAX_PERIOD``, ``lock_extensions`` at most ``MAX_LOCK_EXTENSIONS`` and ``n_strobe`` at
    most ``MAX_SEGMENTS``, ``atol`` > 0 and ``strobe_tol`` in (0, 1) (``ValueError`` naming
    the field).
    """

    x0: float = 0.0
    v0: float = 0.0
    transient_min: float = 100.0
    transient_periods: float = 1.0
    transient_efolds: float = 25.0
    window_min: float = 100.0
    window_periods: float = 1.0
    modulation_cap: float = 100.0
    q_max: int = 4
    m_max: int = 4
    lock_extensions: int = 3
    n_strobe: int = 12
    strobe_tol: float = 1e-6
    method: str = "auto"
    rtol: float = 1e-6
    atol: float = 1e-8
    max_event_rate: float = 200.0
    max_steps_per_tau: float = MAX_STEPS_PER_TAU
    max_steps: float = MAX_STEPS_PER_CALL
    lyapunov: bool = False

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "lyapunov":
                object.__setattr__(self, f.name, check_bool(f.name, v))
                continue
            if f.name == "method":
                if not isinstance(v, str):
                    raise TypeError(f"method must be 'auto', 'exact' or 'event', {got(v)}")
                if v not in ("auto", "exact", "event"):
                    raise ValueError(f"method must be 'auto', 'exact' or 'event', got {v!r}")
                continue
            if f.name in _INT_SETTINGS:  # counts: 12.0 is a TypeError, not silently 12
                n = check_int(f.name, v, 0)
                if n > _INT_SETTINGS[f.name]:
                    raise ValueError(f"{f.name} must be an integer <= {_INT_SETTINGS[f.name]}, "
                                     f"{got(v)}")
                object.__setattr__(self, f.name, n)
            elif f.name in ("x0", "v0"):  # a state as large as no parameter may be
                object.__setattr__(self, f.name, check_bounded_real(f.name, v, PARAM_LIMIT))
            else:  # TypeError for a non-number, ValueError for NaN or inf
                object.__setattr__(self, f.name, check_finite_real(f.name, v))
        check_rtol(self.rtol)
        for name in ("transient_min", "transient_periods", "transient_efolds",
                     "window_periods"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("window_min", "max_event_rate", "strobe_tol", "modulation_cap", "atol",
                     "max_steps_per_tau", "max_steps"):
            if getattr(self, name) <= 0:  # (atol as in run_stats and simulate)
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if self.strobe_tol >= 1.0:  # relative to the orbit's size: any orbit would match
            raise ValueError(f"strobe_tol must be < 1, got {self.strobe_tol!r}")

    def method_code(self, params: OscillatorParams) -> int:
        if self.method == "auto":
            return METHOD_EXACT if params.is_coulomb else METHOD_EVENT
        if self.method == "exact" and not params.is_coulomb:
            raise ValueError(f"method 'exact' needs the Coulomb law (b1 = b3 = 0), got the "
                             f"{params.law_spec.name} law")
        return METHODS[self.method]


def settings_with(settings: SweepSettings | None, overrides: Mapping[str, object]
                  ) -> SweepSettings:
    """The settings of a sweep: ``settings`` (None: the defaults) with the single fields
    ``overrides`` replaced; an unknown field is a ``ValueError`` naming it, ``settings`` of
    another type a ``TypeError``."""
    known = {f.name for f in fields(SweepSettings)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ValueError(f"unknown setting(s) {unknown}; expected some of {sorted(known)}")
    if settings is None:
        return SweepSettings(**overrides)  # type: ignore[arg-type]
    if not isinstance(settings, SweepSettings):
        raise TypeError(
            "settings must be a fricenv.SweepSettings or None (single settings can also be "
            f"passed as keyword arguments), {got(settings)}"
        )
    if overrides:
        return SweepSettings(**{**asdict(settings), **overrides})
    return settings


@dataclass(frozen=True)
class CellPlan:
    """Per-nu time spans of a sweep (arrays of the nu grid's length)."""

    nu_exact: np.ndarray  # p/q when rational with small q, else nu
    q: np.ndarray  # tested denominator, 0 if not tested
    t_transient: np.ndarray
    t_segment: np.ndarray  # window = n_segment * t_segment
    n_segment: np.ndarray
    tries: np.ndarray  # windows allowed until the response locks (0: no periodicity test)


def modulation_period(eta: float, nu: np.ndarray, cap: float) -> np.ndarray:
    """Slowest time scale of the two-tone forcing, ``2 pi / (eta dist(nu, Z))``.

    The second tone's phase drifts against the nearest harmonic ``n`` of the first one at the
    rate ``eta |nu - n|``; over that period the forcing's waveform runs through all its
    shapes (for ``nu < 1/2`` it is the slow tone's period, near ``nu = 1`` the beat period).
    Integer ``nu`` gives an unmodulated forcing: ``T1 = 2 pi / eta``. Capped at ``cap * T1``.
    """
    nu = np.asarray(nu, dtype=float)
    t1 = 2.0 * math.pi / eta
    d = np.abs(nu - np.round(nu))
    with np.errstate(divide="ignore"):
        t_mod = np.where(d > 1e-12, t1 / np.where(d > 1e-12, d, 1.0), t1)
    return np.minimum(t_mod, cap * t1)


def plan_cells(params: OscillatorParams, nu: np.ndarray, settings: SweepSettings) -> CellPlan:
    """Transient, window and stroboscopic segments for each nu (module docstring)."""
    nu = np.asarray(nu, dtype=float)
    q = rational_denominators(nu, settings.q_max)
    if settings.n_strobe < 2 * max(settings.m_max, 1) + 1:
        q[:] = 0  # too few samples to test any period: do not pretend
    nu_exact = exact_rationals(nu, q)
    t1 = 2.0 * math.pi / params.eta
    t_mod = modulation_period(params.eta, nu_exact, settings.modulation_cap)
    # damping of slip near v = V (a friction that falls with speed pumps energy in)
    lam_eff = params.lam - params.law_spec.near_belt_slope(params.law_values(), params.xfk,
                                                            params.xfs)
    decay = settings.transient_efolds * 2.0 / lam_eff if lam_eff > 0 else 0.0
    t_tr = np.maximum(max(settings.transient_min, decay), settings.transient_periods * t_mod)
    win = np.maximum(settings.window_min, settings.window_periods * t_mod)
    tc = q * t1
    n_seg = np.where(q > 0, np.maximum(np.ceil(win / np.where(q > 0, tc, 1.0) - 1e-9),
                                        settings.n_strobe), 1)
    over = ~(n_seg <= MAX_SEGMENTS)  # tested as floats: the int64 cast would wrap (or NaN)
    if over.any():
        i = int(np.argmax(over))
        cause = ("window_min" if settings.window_min >= settings.window_periods * t_mod[i]
                 else "window_periods")
        raise ValueError(
            f"nu = {float(nu[i])!r}: a window of {win[i]:.4g} would keep {_count(n_seg[i])} "
            f"stroboscopic samples (at most {MAX_SEGMENTS}), one per common forcing period of "
            f"{tc[i]:.4g}; check eta = {params.eta!r} and the setting {cause} = "
            f"{getattr(settings, cause)!r}")
    n_seg = n_seg.astype(np.int64)
    t_seg = np.where(q > 0, tc, win)
    tries = np.where(q == 1, 1 + settings.lock_extensions, np.where(q > 0, 1, 0))
    return CellPlan(nu_exact, q, t_tr, t_seg, n_seg, tries.astype(np.int64))


def _count(n: float) -> str:
    """A float count for a message: whole digits, or 4 significant ones when huge."""
    return f"{n:.0f}" if n < 1e15 else f"{n:.4g}"


def check_n_threads(n: object) -> int:
    """``n`` as a thread count numba can run, else ``TypeError`` / ``ValueError`` naming it."""
    n = check_int("n_threads", n)
    most = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
    if not 1 <= n <= most:
        raise ValueError(f"n_threads must be in [1, {most}], got {n}")
    return n


class _Threads:
    """Temporarily set numba's thread count (None: leave it)."""

    def __init__(self, n: int | None) -> None:
        self.n = n
        self.old: int | None = None

    def __enter__(self) -> None:
        if self.n is not None:
            n = check_n_threads(self.n)
            self.old = numba.get_num_threads()
            numba.set_num_threads(n)

    def __exit__(self, *exc: object) -> None:
        if self.old is not None:
            numba.set_num_threads(self.old)


def _check_cells(P_cells: np.ndarray, t_transient: np.ndarray, t_segment: np.ndarray,
                 n_segment: np.ndarray, tries: np.ndarray) -> None:
    """``ValueError`` before a sweep whose cells would run for hours or fill the memory."""
    n_segment = np.asarray(n_segment)
    if n_segment.size and n_segment.max() > MAX_SEGMENTS:
        i = int(np.argmax(n_segment))
        raise ValueError(
            f"a cell would keep {n_segment[i]} stroboscopic samples (at most {MAX_SEGMENTS}): "
            f"its window is that many common forcing periods of {t_segment[i]:.4g} (or "
            f"n_strobe asks for them); check eta = {P_cells[i, P_W1]:.6g} and the settings "
            "window_min, window_periods and n_strobe"
        )
    longest = np.asarray(t_transient) + np.asarray(t_segment) * n_segment * np.maximum(
        np.asarray(tries), 1)  # the transient plus every window a cell may be given
    check_scan_steps(
        P_cells, np.ascontiguousarray(longest, dtype=np.float64),
        "a cell's span is its transient (at least transient_efolds * 2 / (lam - b1)) plus "
        "its windows: check these values and the settings transient_min, transient_efolds "
        "and window_min")


#: What each column of a parameter row is (layout ``params.P_*``), for messages.
_P_COLUMNS = ("lam", "V", "xfk", "xfs", "u1", "u2", "w1 = eta", "w2 = nu * eta", "law code",
              "law parameter 1", "law parameter 2", "law parameter 3")
assert len(_P_COLUMNS) == N_PARAMS


def _check_rows(P: np.ndarray) -> None:
    """``ValueError`` naming the first entry of ``P`` (rows in layout ``params.P_*``) that
    :class:`OscillatorParams` would refuse: the kernels would run it to numbers without a
    word (a NaN row to status 2, lam = -5 or xfs < xfk to made-up statistics)."""
    big = ~(np.abs(P) <= PARAM_LIMIT)  # NaN and inf too
    if big.any():
        i, j = (int(k) for k in np.argwhere(big)[0])
        raise ValueError(f"P_cells[{i}, {j}] ({_P_COLUMNS[j]}) must be finite and within "
                         f"+-{PARAM_LIMIT:g} (as every parameter), got {float(P[i, j])!r}")
    rules = ((P_LAM, P[:, P_LAM] >= 0.0, "must be >= 0"),
             (P_W1, P[:, P_W1] > 0.0, "must be > 0"),
             (P_W2, P[:, P_W2] >= 0.0, "must be >= 0"),
             (P_U1, P[:, P_U1] >= 0.0, "must be >= 0"),
             (P_U2, P[:, P_U2] >= 0.0, "must be >= 0"),
             (P_XFK, P[:, P_XFK] >= 0.0, "must be >= 0"),
             (P_XFS, P[:, P_XFS] >= P[:, P_XFK], "must be >= xfk"),
             (P_LAW, np.isin(P[:, P_LAW], [law.code for law in LAWS.values()]),
              f"must be a friction law's code ({ {k: v.code for k, v in LAWS.items()} })"))
    for j, ok, why in rules:
        if not ok.all():
            i = int(np.argmin(ok))
            raise ValueError(f"P_cells[{i}, {j}] ({_P_COLUMNS[j]}) {why}, got "
                             f"{float(P[i, j])!r}"
                             + (f" (xfk = {float(P[i, P_XFK])!r})" if j == P_XFS else ""))


def run_cells(P_cells: np.ndarray, t_transient: np.ndarray, t_segment: np.ndarray,
              n_segment: np.ndarray, tries: np.ndarray, settings: SweepSettings,
              method: int, n_threads: int | None = None,
              stop_requested: Callable[[], bool] | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run independent cells in parallel: returns (stats[n, N_STATS], status[n], period[n]).

    ``P_cells`` holds one parameter vector per row (layout ``params.P_*``), each obeying
    :class:`OscillatorParams`' rules; ``n_segment`` is at most ``MAX_SEGMENTS`` and ``tries``
    at most ``1 + MAX_LOCK_EXTENSIONS``. This is the engine under :func:`regime_map`; it is
    public so that other scans (e.g. amplitude versus eta) reuse the same measured
    quantities. A cell the kernel finished whose motion ran away (:mod:`fricenv.divergence`)
    gets status ``STATUS_DIVERGED``; its statistics are kept, but they are no result.

    Stopping: Ctrl-C (or SIGTERM inside :func:`fricenv.calls.sweep_signals`) stops the
    running cells within ``BUDGET_CHECK_STEPS`` steps and raises
    :class:`~fricenv.calls.SweepInterrupted`, whose ``results`` are the three outputs with
    every finished cell; ``stop_requested()``, if given, is polled every ``JOIN_POLL``
    seconds and, once true, stops the cells the same way but returns. Cells not finished
    are left at NaN statistics and status ``STATUS_NOT_RUN``; a cell depends on its own row
    only, so running them later gives what an uninterrupted run gives.
    """
    if not isinstance(settings, SweepSettings):  # its fields are the kernel's arguments
        raise TypeError(f"settings must be a fricenv.SweepSettings, {got(settings)}")
    if check_int("method", method) not in (METHOD_EXACT, METHOD_EVENT):  # not True or 1.0
        raise ValueError(f"method must be METHOD_EXACT ({METHOD_EXACT}) or METHOD_EVENT "
                         f"({METHOD_EVENT}), got {method!r}")
    P_cells = np.ascontiguousarray(real_array(P_cells, "P_cells must be an array of real "
                                              "numbers"), dtype=np.float64)
    if P_cells.ndim != 2 or P_cells.shape[1] != N_PARAMS:
        raise ValueError(f"P_cells must have shape (n, {N_PARAMS}) (a row of params.P_* per "
                         f"cell), got {P_cells.shape}")
    _check_rows(P_cells)
    n = P_cells.shape[0]
    spans = {}
    for name, a in (("t_transient", t_transient), ("t_segment", t_segment),
                    ("n_segment", n_segment), ("tries", tries)):
        a = real_array(a, f"{name} must be an array of real numbers")
        if a.shape != (n,):  # the kernel reads one entry per cell, unchecked
            raise ValueError(f"{name} must have one entry per cell, shape ({n},), got {a.shape}")
        spans[name] = a
    bad = ~np.isfinite(spans["t_transient"]) | (spans["t_transient"] < 0)
    bad |= ~np.isfinite(spans["t_segment"]) | (spans["t_segment"] <= 0)
    bad |= (spans["n_segment"] < 1) | (spans["tries"] < 0)
    bad |= (spans["n_segment"] % 1 != 0) | (spans["tries"] % 1 != 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"cell {i}: need a finite t_transient >= 0, t_segment > 0 and whole "
                         f"n_segment >= 1, tries >= 0; got {spans['t_transient'][i]!r}, "
                         f"{spans['t_segment'][i]!r}, {spans['n_segment'][i]!r}, "
                         f"{spans['tries'][i]!r}")
    for name, most in (("n_segment", MAX_SEGMENTS), ("tries", 1 + MAX_LOCK_EXTENSIONS)):
        over = spans[name] > most  # checked as floats: the int64 cast would wrap 1e20
        if over.any():
            i = int(np.argmax(over))
            raise ValueError(f"cell {i}: {name} must be at most {most}, got "
                             f"{float(spans[name][i])!r}")
    if method == METHOD_EXACT and n:
        other = ~closed_form_rows(P_cells[:, P_LAW])
        if other.any():  # the closed form would silently drop the law's speed dependence
            i = int(np.argmax(other))
            raise ValueError(f"cell {i}: METHOD_EXACT needs the Coulomb law, got the "
                             f"{law_of_code(P_cells[i, P_LAW]).name} law")
    t_transient, t_segment = spans["t_transient"], spans["t_segment"]
    n_segment, tries = spans["n_segment"].astype(np.int64), spans["tries"].astype(np.int64)
    # A cell the kernel never writes must not read as a result (np.empty once returned
    # stale memory with status OK): NaN statistics and a status that is not a layout one.
    out_stats = np.full((n, N_STATS), np.nan)
    out_status = np.full(n, STATUS_NOT_RUN, dtype=np.int64)
    out_period = np.zeros(n, dtype=np.int64)
    if n == 0:
        return out_stats, out_status, out_period
    _check_cells(P_cells, t_transient, t_segment, n_segment, tries)
    kernel_spans = (np.ascontiguousarray(t_transient, dtype=np.float64),
             np.ascontiguousarray(t_segment, dtype=np.float64),
             np.ascontiguousarray(n_segment, dtype=np.int64),
             np.ascontiguousarray(tries, dtype=np.int64))
    finished = True
    cells = CellSpans(P_cells, *kernel_spans)
    outputs = CellOutputs(out_stats, out_status, out_period)
    try:
        with _Threads(n_threads), parallel_section():
            for cell_method, rows in _method_groups(P_cells, method):
                finished = _run_group(rows, cells, _cell_run(settings, cell_method), outputs,
                                      stop_requested)
                if not finished:  # stopped on request: the other groups stay unrun
                    break
    except KeyboardInterrupt as stop:
        _finish_cells(P_cells, kernel_spans, settings, out_stats, out_status, stopped=True)
        raise calls.SweepInterrupted((out_stats, out_status, out_period),
                                     getattr(stop, "signum", None)) from None
    _finish_cells(P_cells, kernel_spans, settings, out_stats, out_status, not finished)
    return out_stats, out_status, out_period


def _finish_cells(P_cells: np.ndarray, spans: tuple[np.ndarray, ...],
                  settings: SweepSettings, out_stats: np.ndarray, out_status: np.ndarray,
                  stopped: bool) -> None:
    """The kernels' outputs as results: a stopped run's cells that were cut short (their
    budget slot was lowered, so they read ``STATUS_STEP_BUDGET``) become unrun, and a
    finished cell whose motion ran away gets ``STATUS_DIVERGED``."""
    if stopped:  # (a cell over its own budget before the stop is run again: same result)
        out_status[out_status == STATUS_STEP_BUDGET] = STATUS_NOT_RUN
        out_stats[out_status == STATUS_NOT_RUN] = np.nan
    else:
        missed = np.flatnonzero(out_status == STATUS_NOT_RUN)
        if missed.size:  # an exception inside prange is lost: say so rather than return them
            raise RuntimeError(f"the cell kernel left {missed.size} cell(s) unrun (first: "
                               f"cell {int(missed[0])}); this is a bug in fricenv.sweep")
    # A window stuck throughout sums its stick phases a few ulps beyond its duration.
    np.minimum(out_stats[:, ST_STICK_TIME], out_stats[:, ST_DURATION],
               out=out_stats[:, ST_STICK_TIME])
    t_transient, t_segment, n_segment, tries = spans
    longest = t_transient + t_segment * n_segment * np.maximum(tries, 1)
    out_status[(out_status == STATUS_OK) & diverged(
        P_cells, settings.x0, settings.v0, longest, out_stats, vr2_measured=False)] = (
        STATUS_DIVERGED)


def _method_groups(P_cells: np.ndarray, method: int) -> list[tuple[int, np.ndarray]]:
    """The cells each method runs: METHOD_EXACT's cells with a tone too close to resonance
    for the closed form go to the event method (as ``core.advance`` does inside), so each
    kernel compiles one method's code only."""
    everything = np.arange(P_cells.shape[0])
    if method != METHOD_EXACT:
        return [(METHOD_EVENT, everything)]
    ok = conditioned_rows(P_cells)
    return [(m, everything[sel]) for m, sel in ((METHOD_EXACT, ok), (METHOD_EVENT, ~ok))
            if sel.any()]


def _cell_run(settings: SweepSettings, method: int) -> CellRun:
    """What the cell kernels read of ``settings``, with the cells' ``method``."""
    return CellRun(float(settings.x0), float(settings.v0), int(method), float(settings.rtol),
                   float(settings.atol), float(settings.max_event_rate), int(settings.m_max),
                   float(settings.strobe_tol), float(settings.max_steps_per_tau),
                   float(settings.max_steps))


def _run_group(rows: np.ndarray, cells: CellSpans, run: CellRun, outputs: CellOutputs,
               stop_requested: Callable[[], bool] | None) -> bool:
    """Run the cells ``rows`` by the parallel kernel of ``run.method`` into the outputs'
    rows, in a worker thread that Ctrl-C or ``stop_requested`` stops
    (:func:`fricenv.calls.run_stoppable`); whether it ran to its end. A cell depends on its
    own row only, so which cells share a call changes no result."""
    whole = rows.size == cells.P.shape[0]
    pick = (lambda a: a) if whole else (lambda a: np.ascontiguousarray(a[rows]))
    out = CellOutputs(*(pick(a) for a in outputs))
    works = np.empty((numba.get_num_threads(), N_WORK))  # a workspace row per worker
    next_cell = np.zeros(1, dtype=np.int64)
    spans = CellSpans(*(pick(a) for a in cells))
    kernel = CELL_KERNELS[run.method]

    def abort() -> None:  # (see cell_kernels._cells_with)
        next_cell[0] = rows.size
        works[:, W_MAX_STEPS_CALL] = calls.ABORT

    try:
        return calls.run_stoppable(lambda: kernel(spans, run, out, works, next_cell), abort,
                                   stop_requested)
    finally:  # also when stopped: the finished cells are kept
        if not whole:
            for dst, src in zip(outputs, out, strict=True):
                dst[rows] = src


# -- the one path from parameters to labels ------------------------------------------------
#: Column of the kernels' parameter row that each field of a cell's values sets, beside
#: ``u0`` (both amplitudes, unless ``u1`` / ``u2`` set one) and ``nu`` (the second tone's
#: frequency, ``nu_exact * eta``).
_COLUMN = {"lam": P_LAM, "V": P_V, "xfk": P_XFK, "xfs": P_XFS,
           "eta": P_W1, "u1": P_U1, "u2": P_U2}
#: Fields of :class:`OscillatorParams` that a cell's values may set (a friction law's
#: parameters where the base has that law).
CELL_FIELDS = ("u0", "nu", *_COLUMN, *OWNER)
#: Fields the time spans of a plant of the paper's laws depend on (:func:`plan_cells`
#: reads eta and lam - b1; nu is its argument); ``OscillatorParams.plan_fields`` gives any
#: plant's.
PLAN_FIELDS = ("eta", "lam", "b1")


class CellInputs(NamedTuple):
    """What :func:`run_cells` and :func:`~fricenv.regimes.classify` take for each cell (one
    entry, or row, per cell)."""

    P: np.ndarray  # parameter rows, layout params.P_*
    t_transient: np.ndarray
    t_segment: np.ndarray
    n_segment: np.ndarray  # int64
    tries: np.ndarray  # int64
    method: np.ndarray  # int64: METHOD_EXACT or METHOD_EVENT
    nu: np.ndarray  # the values' nu (the label's), not the plan's nu_exact
    q: np.ndarray  # int64: tested denominator of nu, 0 if untested

    def check(self) -> None:
        """``ValueError`` before any cell runs, for a row :class:`OscillatorParams` would
        refuse or a cell that would run for hours or fill the memory."""
        _check_rows(self.P)
        _check_cells(self.P, self.t_transient, self.t_segment, self.n_segment, self.tries)


class CellResults(NamedTuple):
    """What a regime map stores of each cell (one entry, or row, per cell)."""

    stats: np.ndarray  # float64 (n, N_STATS), layout ST_*; NaN for a cell not run
    status: np.ndarray  # int64: kernel status, STATUS_NOT_RUN for a cell not run
    period: np.ndarray  # int64: period in common forcing periods, 0 none or untested
    labels: np.ndarray  # int8: Regime values, NOT_COMPUTED for a cell not run
    lyapunov: np.ndarray  # float64: largest Lyapunov exponent, NaN if not measured


def _cell_values(values: object) -> dict[str, np.ndarray]:
    """``values`` as 1-d float arrays of one length, each naming a field of
    :data:`CELL_FIELDS` (else ``TypeError`` / ``ValueError`` naming the bad entry)."""
    if not isinstance(values, Mapping):
        raise TypeError(f"values must be a mapping from parameter names to 1-d arrays, "
                        f"{got(values)}")
    if not values:
        raise ValueError("values is empty: give at least one field, e.g. {'u0': [1.0]}")
    out = {}
    for name, a in values.items():
        if name not in CELL_FIELDS:
            raise ValueError(f"values: {name!r} is not a field a cell can set; expected "
                             f"some of {list(CELL_FIELDS)}")
        arr = np.asarray(real_array(a, f"values[{name!r}] must be a 1-d array of real "
                                       "numbers"), dtype=np.float64)
        if arr.ndim != 1:
            raise ValueError(f"values[{name!r}] must be 1-d, got shape {arr.shape}")
        out[name] = arr
    sizes = {k: a.size for k, a in out.items()}
    if len(set(sizes.values())) > 1:
        raise ValueError(f"values must all have one length, got {sizes}")
    return out


def cell_inputs(base: OscillatorParams, values: Mapping[str, object],
                settings: SweepSettings) -> CellInputs:
    """Kernel inputs of the cells ``values`` (one 1-d array per field of
    :data:`CELL_FIELDS`, all of one length; the other fields are ``base``'s): each cell's
    parameter row is ``base.replace(**cell).to_array()`` with the second tone at
    ``nu_exact * eta``, and its spans are those :func:`plan_cells` gives its nu (elementwise
    in nu, so any subset of a grid gets the grid's spans). ``method="auto"`` picks each
    cell's method from its own law."""
    if not isinstance(base, OscillatorParams):
        raise TypeError(f"base must be an OscillatorParams, {got(base)}")
    if not isinstance(settings, SweepSettings):
        raise TypeError(f"settings must be a fricenv.SweepSettings, {got(settings)}")
    vals = _cell_values(values)
    n = next(iter(vals.values())).size
    P = np.repeat(base.to_array()[None, :], n, axis=0)
    u0 = vals.get("u0", np.full(n, base.u0))
    P[:, P_U1] = u0 if base.u1 is None else base.u1
    P[:, P_U2] = u0 if base.u2 is None else base.u2
    for k, col in _COLUMN.items():
        if k in vals:
            P[:, col] = vals[k]
    P[:, P_LAW:] = base.law_rows(vals, n)
    plan_fields = base.plan_fields()
    nu = vals.get("nu", np.full(n, base.nu))
    t_tr, t_seg, nu_exact = np.empty(n), np.empty(n), np.empty(n)
    n_seg, tries, q = (np.empty(n, dtype=np.int64) for _ in range(3))
    if any(k in vals for k in plan_fields):
        keys = np.stack([vals.get(k, np.full(n, getattr(base, k))) for k in plan_fields], 1)
        groups, inverse = np.unique(keys, axis=0, return_inverse=True)
    else:  # (a regime map's chunk: the base's plan for every cell)
        groups = np.array([[getattr(base, k) for k in plan_fields]])
        inverse = np.zeros(n, dtype=np.int64)
    for g, key in enumerate(groups):  # one plan per distinct (eta, lam, b1)
        idx = np.flatnonzero(inverse.ravel() == g)
        p = base.replace(**dict(zip(plan_fields, (float(v) for v in key), strict=True)))
        grid, where = np.unique(nu[idx], return_inverse=True)
        plan = plan_cells(p, grid, settings)
        for dst, src in ((t_tr, plan.t_transient), (t_seg, plan.t_segment),
                         (n_seg, plan.n_segment), (tries, plan.tries), (q, plan.q),
                         (nu_exact, plan.nu_exact)):
            dst[idx] = src[where.ravel()]
    P[:, P_W2] = nu_exact * P[:, P_W1]
    if settings.method == "auto":
        method = np.where(closed_form_rows(P[:, P_LAW]), METHOD_EXACT,
                          METHOD_EVENT).astype(np.int64)
    else:
        method = np.full(n, METHODS[settings.method], dtype=np.int64)
    return CellInputs(P, t_tr, t_seg, n_seg, tries, method, nu, q)


def measure_cells(base: OscillatorParams, values: Mapping[str, object],
                  settings: SweepSettings, n_threads: int | None = None,
                  stop_requested: Callable[[], bool] | None = None) -> CellResults:
    """Measure and label the cells ``values`` (see :func:`cell_inputs`): every regime
    map, ``cell_statistics`` and atlas cell goes through here, so a cell gets the same
    statistics and label whichever of them asks.

    The cells run by :func:`run_cells`, one call per method present; labels come from
    :func:`~fricenv.regimes.classify` with the stick -> slip count, so a block stuck all
    window long is ``STUCK``. Stopping is :func:`run_cells`': ``stop_requested()`` turning
    true returns the cells finished so far, Ctrl-C raises
    :class:`~fricenv.calls.SweepInterrupted` whose ``results`` are that
    :class:`CellResults`; a cell not run has NaN statistics, status ``STATUS_NOT_RUN`` and
    label ``NOT_COMPUTED``.
    """
    cells = cell_inputs(base, values, settings)
    n = cells.P.shape[0]
    stats = np.full((n, N_STATS), np.nan)
    status = np.full(n, STATUS_NOT_RUN, dtype=np.int64)
    period = np.zeros(n, dtype=np.int64)
    stopped = None
    for m in np.unique(cells.method):
        idx = np.flatnonzero(cells.method == m)
        try:
            out = run_cells(cells.P[idx], cells.t_transient[idx], cells.t_segment[idx],
                            cells.n_segment[idx], cells.tries[idx], settings, int(m),
                            n_threads, stop_requested)
        except calls.SweepInterrupted as stop:
            stopped, out = stop, stop.results
        stats[idx], status[idx], period[idx] = out
        if stopped is not None or np.any(out[1] == STATUS_NOT_RUN):
            break  # stopped: the other methods' cells stay unrun
    labels = np.zeros(n, dtype=np.int8)
    if n:
        labels[:] = classify(stats[:, ST_N_STICK], stats[:, ST_STICK_TIME],
                             stats[:, ST_N_REVERSAL], cells.nu, cells.q, period, status,
                             stats[:, ST_N_SLIP])
    labels[status == STATUS_NOT_RUN] = NOT_COMPUTED
    exponent = np.full(n, np.nan)
    if settings.lyapunov and stopped is None:
        from .stability import lyapunov_of_cells

        exponent = lyapunov_of_cells(cells, settings, status)
    results = CellResults(stats, status, period, labels, exponent)
    if stopped is not None:
        stopped.results = results
        raise stopped
    return results
