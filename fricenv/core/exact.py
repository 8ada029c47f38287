"""The exact runner (Coulomb law): closed-form slip steps, exact stick.

The runner is a loop over the output grid's intervals, each split into equal scan steps;
a step is a slip step (``_slip_step``: trial length, v's extremum, contact search,
statistics) or a stick step (``_stick_step``), and a switch ends it early. A step takes
the scan's state as a :class:`Motion` and its bounds as a :class:`ScanStep`, and returns a
:class:`StepEnd`; the step bodies are inlined into the scan (``called_once``), where the
records cost nothing.
"""

import math
from typing import NamedTuple

from ..jit import kernel
from ..layout import (
    EVENT_SLIP,
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    ST_DURATION,
    ST_N_STEPS,
    ST_STICK_TIME,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STEP_BUDGET,
)
from .closed_form import (
    Point,
    _forcing,
    _homog,
    _jerk,
    _rotate,
    _rotate_by,
    _slip_at,
    _slip_mid_and_end,
    _slip_start,
    _slip_with,
)
from .constants import _STATUS_NEAR_RESONANCE, COUNT_SLACK, GRID_REL_TOL, SCAN_ALLOWANCE
from .contacts import _contact_outcome, _contact_time, _start_slope, _stick_outcome
from .context import _scan_cap, _setup_context
from .proofs import _extremum_matters, _one_extremum_at_most
from .recording import _log_event, _write_output, recording
from .roots import K_SLIP_H, K_SLIP_V, _extremum_closed, _root_closed
from .state import Phases, Tones, _end_call, _note_v, _note_x
from .stats import _slip_stats
from .stick import _stick_exit_time, _stick_start, _stick_trial
from .trig import _renorm, _sincos, _wrap
from .whole_interval import _whole_interval
from .workspace import (
    C_DV,
    C_DX,
    C_LAM,
    C_P2,
    C_U1,
    C_U2,
    C_V,
    C_VDD_H,
    C_VDD_P,
    C_VDDD_H,
    C_VDDD_P,
    C_W1,
    C_W2,
    C_XFK,
    T_NEAR_RES,
    W_C1,
    W_C2,
    W_KEY_H,
    W_KEY_LAM,
    W_KEY_W1,
    W_KEY_W2,
    W_M11,
    W_M12,
    W_M21,
    W_M22,
    W_MC1,
    W_MC2,
    W_MS1,
    W_MS2,
    W_PH1,
    W_PH2,
    W_R11,
    W_R12,
    W_R21,
    W_R22,
    W_RC1,
    W_RC2,
    W_RS1,
    W_RS2,
    W_S1,
    W_S2,
    W_SKIP_EXTREMA,
    W_T_KEY,
    W_T_KEY2,
    _budget_check,
)


class Motion(NamedTuple):
    """The scan's state between two steps: the mode (-1/+1: slip below/above the belt, 0:
    stick), x, v, the slip acceleration v' (carried from a step's end to the next one's
    start) and the tones' cos/sin."""

    mode: float
    x: float
    v: float
    acc: float
    tones: Tones


class ScanStep(NamedTuple):
    """What bounds a scan step: its length ``L`` at most, the scan's cap, and whether it is a
    regular step of the output grid (``on_grid``), whose transition ``reg`` and tones'
    rotation ``rot`` are cached (4-tuples, see ``_regular_step``)."""

    L: float
    cap: float
    on_grid: bool
    reg: tuple[float, float, float, float]
    rot: tuple[float, float, float, float]


class StepEnd(NamedTuple):
    """A scan step's outcome: its length ``tau``, whether it was halved, whether it is still
    a regular grid step (``on_grid``), the switch that ended it (``layout.EVENT_*``, 0:
    none) and the motion at its end."""

    tau: float
    halved: bool
    on_grid: bool
    kind: int
    motion: Motion


class Trend(NamedTuple):
    """h = sd (v - V) and its first two derivatives at an instant."""

    h: float
    d: float
    q: float


class Curvature(NamedTuple):
    """Bounds on v's second and third derivatives over a slip step, in absolute value."""

    vdd: float
    vddd: float


class Trial(NamedTuple):
    """A slip step's length once tried (``_slip_trial``): ``L``, whether it was halved,
    whether it is still a regular grid step, v at its midpoint (0 on the grid, where the
    caller takes it from the cached half step) and the state at its end."""

    L: float
    halved: bool
    on_grid: bool
    v_mid: float
    end: Point


class Extremum(NamedTuple):
    """v's interior extremum on a slip step: its time ``t`` (-1 if not searched), v, h and
    h'' there."""

    t: float
    v: float
    h: float
    q: float


@kernel
def _start_phases(S, cx):
    """The tones' cos/sin at the call's start: from the workspace's cache when the phase
    angles are those the last call ended on (four libm calls spared), else computed."""
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    if ph1 == cx[W_PH1]:
        c1, s1 = cx[W_C1], cx[W_S1]
    else:
        c1, s1 = math.cos(ph1), math.sin(ph1)
    if ph2 == cx[W_PH2]:
        c2, s2 = cx[W_C2], cx[W_S2]
    else:
        c2, s2 = math.cos(ph2), math.sin(ph2)
    return Tones(c1, s1, c2, s2)


@kernel
def _run_exact(P, S, t_span, stats, max_events, rec, cx):
    """Advance S by t_span with the closed-form solver; see ``advance``. Changes nothing
    and returns _STATUS_NEAR_RESONANCE when a tone is too close to resonance for it.

    ``rec``: a :class:`~fricenv.core.recording.Recording` to fill (empty: stats only).
    A stats-only call that reads no extrema is first tried as one whole-call step when
    the scan would split it into several steps, or when it starts stuck (the stick proof
    is cheaper than a scan step). A slip call the scan covers in one step gains nothing
    from it: the (v - V)^2 constants a retuned tone needs cost more than that step.
    Otherwise, or when its proof fails, the scan runs.
    """
    _setup_context(P, cx)
    if cx[W_T_KEY + T_NEAR_RES] != 0.0 or cx[W_T_KEY2 + T_NEAR_RES] != 0.0:
        return _STATUS_NEAR_RESONANCE
    tones = _start_phases(S, cx)
    cap = _scan_cap(P, cx[W_SKIP_EXTREMA] == 1.0)
    if (not recording(rec) and cx[W_SKIP_EXTREMA] == 1.0 and (t_span > cap or S[S_MODE] == 0.0)
            and _whole_interval(cx, S, t_span, stats, tones.c1, tones.s1, tones.c2, tones.s2)):
        return STATUS_OK
    return _scan_exact(S, t_span, stats, max_events, rec, cx, cap, tones)


@kernel
def _grid(rec, t_span):
    """The call's output grid: its origin, number of intervals and regular interval
    length (a stats-only call is one interval, [0, t_span])."""
    if not recording(rec):
        return 0.0, 1, t_span
    n_int = rec.out_t.shape[0] - 1
    return rec.out_t[0], n_int, rec.out_t[1] - rec.out_t[0] if n_int > 0 else t_span


@kernel
def _grid_interval(rec, j, n_int, origin, t_stop):
    """Output interval ``j`` [ta, tb] in the call's time (the last one ends at t_stop)."""
    if not recording(rec):
        return 0.0, t_stop
    ta = rec.out_t[j] - origin
    tb = t_stop if j == n_int - 1 else rec.out_t[j + 1] - origin
    return ta, tb


@kernel
def _regular_step(cx, dt_reg, cap):
    """Number and length of the equal scan steps of a regular output interval, and their
    transition constants (``reg``: the homogeneous transition and the tones' rotation over
    a step; the half step's are cached in W_M*).

    Each piece is recomputed only when its own key changed (an agent retuning nu
    invalidates the second tone's rotation, not the rest).
    """
    lam = cx[C_LAM]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    m_reg = max(1, int(math.ceil(dt_reg / cap - COUNT_SLACK)))
    h_reg = dt_reg / m_reg
    same_h = cx[W_KEY_H] == h_reg
    hm = 0.5 * h_reg
    if not (same_h and cx[W_KEY_LAM] == lam):
        cx[W_R11], cx[W_R12], cx[W_R21], cx[W_R22] = _homog(h_reg, lam, cx[C_P2])
        cx[W_M11], cx[W_M12], cx[W_M21], cx[W_M22] = _homog(hm, lam, cx[C_P2])
        cx[W_KEY_LAM] = lam
    if not (same_h and cx[W_KEY_W1] == w1):
        cm, sm = _sincos(w1 * hm)
        cx[W_MC1], cx[W_MS1] = cm, sm
        cx[W_RC1], cx[W_RS1] = cm * cm - sm * sm, 2.0 * sm * cm
        cx[W_KEY_W1] = w1
    if not (same_h and cx[W_KEY_W2] == w2):
        cm, sm = _sincos(w2 * hm)
        cx[W_MC2], cx[W_MS2] = cm, sm
        cx[W_RC2], cx[W_RS2] = cm * cm - sm * sm, 2.0 * sm * cm
        cx[W_KEY_W2] = w2
    cx[W_KEY_H] = h_reg
    reg = (cx[W_R11], cx[W_R12], cx[W_R21], cx[W_R22])
    rot = (cx[W_RC1], cx[W_RS1], cx[W_RC2], cx[W_RS2])
    return m_reg, reg, rot


@kernel
def _closed_acc(cx, mode, x, v, c1, c2):
    """Slip acceleration of the Coulomb law in direction ``mode`` (0 in stick)."""
    if mode == 0.0:
        return 0.0
    return -cx[C_LAM] * v - x - mode * cx[C_XFK] + cx[C_U1] * c1 + cx[C_U2] * c2


@kernel(called_once=True)
def _slip_trial(cx, step, sd, start, bound):
    """The :class:`Trial` of a closed-form slip step from the start in ``cx``
    (``_slip_start``; h there: the :class:`Trend` ``start``): ``step.L``, halved until the
    step may go to the contact search (``_one_extremum_at_most``, with the
    :class:`Curvature` bounds ``bound``).

    On the grid (``step.on_grid``) the cached transition and rotation are used; off it (and
    once halved) both are computed, with v at the midpoint for the quadrature.
    """
    V = cx[C_V]
    L = step.L
    on_grid = step.on_grid
    halved = False
    v_mid = 0.0
    while True:
        if on_grid:
            rot = step.rot
            nc1, ns1, nc2, ns2 = _rotate(cx, rot[0], rot[1], rot[2], rot[3])
            nc1, ns1 = _renorm(nc1, ns1)
            nc2, ns2 = _renorm(nc2, ns2)
            tones = Tones(nc1, ns1, nc2, ns2)
            x1, v1, a1, j1 = _slip_with(cx, L, step.reg, tones)
            end = Point(x1, v1, a1, j1, tones)
        else:
            v_mid, end = _slip_mid_and_end(cx, L)
        h1 = sd * (end.v - V)
        d1 = sd * end.acc
        if _one_extremum_at_most(start.h, start.d, h1, d1, start.q, sd * end.jerk, L,
                                 bound.vdd, bound.vddd, step.cap):
            break
        L *= 0.5
        halved = True
        on_grid = False
    return Trial(L, halved, on_grid, v_mid, end)


@kernel(called_once=True)
def _slip_v_extremum(cx, stats, sd, L, p0, p1, vdd):
    """v's interior extremum on a slip step of length L from ``p0`` to ``p1``
    (:class:`~fricenv.core.closed_form.Point`), where the contact search or the statistics
    need it: an :class:`Extremum` (its time -1 if not searched).

    A caller that reads no extrema needs v's extremum only to tell whether and where h
    first reaches 0: not when h changes sign over the step, as h (one extremum at most)
    then crosses 0 once, bracketed by the step.
    """
    V = cx[C_V]
    lam = cx[C_LAM]
    acc = p0.acc
    a1 = p1.acc
    j0 = p0.jerk
    j1 = p1.jerk
    h0 = sd * (p0.v - V)
    h1 = sd * (p1.v - V)
    t_ext = -1.0
    v_ext = 0.0
    h_ext = 0.0
    q_ext = 0.0
    crossing = h0 > 0.0 and h1 < 0.0 and cx[W_SKIP_EXTREMA] == 1.0
    if acc * a1 < 0.0 and not crossing and _extremum_matters(cx, stats, sd, p0.v, p1.v, acc,
                                                             a1, L, V, vdd):
        # third derivative of v: -lam v'' - v' + g''
        t0 = p0.tones
        t1 = p1.tones
        _, _, gdd0 = _forcing(cx, t0.c1, t0.s1, t0.c2, t0.s2)
        _, _, gdd1 = _forcing(cx, t1.c1, t1.s1, t1.c2, t1.s2)
        t_ext = _extremum_closed(cx, K_SLIP_V, 0.0, L, acc, a1, j0, j1,
                                 gdd0 - lam * j0 - acc, gdd1 - lam * j1 - a1)
        _, v_ext, _, j_ext = _slip_at(cx, t_ext)
        h_ext = sd * (v_ext - V)
        q_ext = sd * j_ext
    return Extremum(t_ext, v_ext, h_ext, q_ext)


@kernel(called_once=True)
def _slip_step(cx, stats, fresh, step, m):
    """One closed-form slip step from the :class:`Motion` ``m`` (direction ``m.mode``),
    bounded by the :class:`ScanStep` ``step``, up to a contact if one comes first; its
    :class:`StepEnd`."""
    V = cx[C_V]
    sd = m.mode
    x = m.x
    v = m.v
    acc = m.acc
    tones = m.tones
    _slip_start(cx, x, v, tones, sd)
    h0 = sd * (v - V)
    d0 = _start_slope(cx, fresh, h0, sd * acc, x, v)
    j0 = _jerk(cx, v, acc, tones.s1, tones.s2)
    r_h = math.sqrt(cx[C_DX] * cx[C_DX] + cx[C_DV] * cx[C_DV])
    vdd = cx[C_VDD_P] + cx[C_VDD_H] * r_h  # bounds |v''| on the step
    vddd = cx[C_VDDD_P] + cx[C_VDDD_H] * r_h  # bounds |v'''|
    trial = _slip_trial(cx, step, sd, Trend(h0, d0, sd * j0), Curvature(vdd, vddd))
    L = trial.L
    p0 = Point(x, v, acc, j0, tones)
    p1 = trial.end
    h1 = sd * (p1.v - V)
    d1 = sd * p1.acc
    ext = _slip_v_extremum(cx, stats, sd, L, p0, p1, vdd)
    te = _contact_time(_root_closed, cx, K_SLIP_H, L, (h0, d0, sd * j0),
                       (h1, d1, sd * p1.jerk), (ext.t, ext.h, ext.q))
    if te >= 0.0:  # the step ends at the contact, where v = V
        v_mid, pe = _slip_mid_and_end(cx, te)
        tau = te
        p_end = Point(pe.x, V, pe.acc, pe.jerk, pe.tones)
    else:
        tau = L
        p_end = p1
        v_mid = trial.v_mid
        if trial.on_grid:
            mc1, ms1, mc2, ms2 = _rotate(cx, cx[W_MC1], cx[W_MS1], cx[W_MC2], cx[W_MS2])
            _, v_mid, _, _ = _slip_with(cx, 0.5 * L,
                                        (cx[W_M11], cx[W_M12], cx[W_M21], cx[W_M22]),
                                        Tones(mc1, ms1, mc2, ms2))
    _slip_stats(cx, stats, tau, ext, p0, p_end, v_mid)
    if te >= 0.0:
        xe = p_end.x
        te_tones = p_end.tones
        new_mode, kind = _contact_outcome(cx, stats, xe, te_tones.c1, te_tones.s1, te_tones.c2,
                                          te_tones.s2, sd)
        a_new = _closed_acc(cx, new_mode, xe, V, te_tones.c1, te_tones.c2)
        return StepEnd(te, trial.halved, False, kind, Motion(new_mode, xe, V, a_new, te_tones))
    # a slip state has sd (v - V) >= 0; v1 may be a few ulps short of V where
    # _unresolved_return saw no contact
    v_end = p1.v if sd * (p1.v - V) >= 0.0 else V
    return StepEnd(L, trial.halved, trial.on_grid, 0, Motion(sd, p1.x, v_end, p1.acc, p1.tones))


@kernel(called_once=True)
def _stick_step(cx, stats, step, m):
    """One exact stick step from the :class:`Motion` ``m``, bounded by the
    :class:`ScanStep` ``step``, up to the stick's end if it comes first; its
    :class:`StepEnd`."""
    V = cx[C_V]
    x = m.x
    tones = m.tones
    f0, fd0, gdd0 = _stick_start(cx, x, tones.c1, tones.s1, tones.c2, tones.s2)
    L, halved, on_grid, held, x1, f1, fd1, gdd1, nc1, ns1, nc2, ns2 = _stick_trial(
        cx, step.L, step.cap, step.on_grid, step.rot, True, f0, fd0, gdd0)
    te = -1.0 if held else _stick_exit_time(cx, L, f0, fd0, gdd0, f1, fd1, gdd1)
    if te >= 0.0:
        xe = x + V * te
        stats[ST_STICK_TIME] += te
        _note_x(stats, xe)
        _note_v(stats, V)
        ec1, es1, ec2, es2 = _rotate_by(cx, te)
        mode = _stick_outcome(cx, stats, xe, ec1, ec2)
        a_new = _closed_acc(cx, mode, xe, V, ec1, ec2)
        return StepEnd(te, halved, False, EVENT_SLIP,
                       Motion(mode, xe, V, a_new, Tones(ec1, es1, ec2, es2)))
    stats[ST_STICK_TIME] += L
    _note_x(stats, x1)
    _note_v(stats, V)
    return StepEnd(L, halved, on_grid, 0, Motion(m.mode, x1, m.v, m.acc,
                                                  Tones(nc1, ns1, nc2, ns2)))


@kernel
def _scan_exact(S, t_span, stats, max_events, rec, cx, cap, tones):
    """The closed-form scan of ``_run_exact``, from its context (``cx``), the scan cap and
    the tones' cos/sin at the start (:class:`~fricenv.core.state.Tones`).

    Steps are aligned with the output grid (``rec.out_t``, or the single interval [t, t +
    t_span] when ``rec`` is empty), each output interval split into equal scan steps whose
    transition constants are computed once, so recording costs nothing extra. An interval
    of length L takes m = ceil(L / cap) scan steps where the scan alone would take L / cap:
    the grid's m - L / cap (under one step an instant) are not charged to the step budget,
    so that a fine grid over a long run (the caller's choice of output, which ``simulate``
    caps) is charged what the same run without outputs is. Those steps still count towards
    the budget checks' cadence: a call lowered to a budget below 0 from another thread
    ends as promptly as ever.
    """
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    # Time runs from 0 inside the call (see _run_event); S[S_T] is only written at the end.
    t_start = S[S_T]
    t_stop = t_span
    origin, n_int, dt_reg = _grid(rec, t_span)
    m_reg, reg, rot = _regular_step(cx, dt_reg, cap)
    x = S[S_X]
    v = S[S_V]
    mode = S[S_MODE]
    t = 0.0
    n_events = 0
    status = STATUS_OK
    fresh = True  # the current phase starts on a switching surface (or at the call start)
    n_call = 0.0  # steps so far, and the step budget's state (see _budget_check)
    n_grid = 0.0  # steps the output grid added, which the budget does not charge
    n_check = 0.0
    t_win = 0.0
    n_win0 = 0.0
    n_scan = SCAN_ALLOWANCE / cap
    _note_v(stats, v)
    _note_x(stats, x)
    _write_output(rec, 0, x, v, mode)
    # acc: at the step start (slip), carried
    m = Motion(mode, x, v, _closed_acc(cx, mode, x, v, tones.c1, tones.c2), tones)
    for j in range(n_int):
        ta, tb = _grid_interval(rec, j, n_int, origin, t_stop)
        length = tb - ta
        if length <= 0.0:
            continue
        regular_interval = abs(length - dt_reg) <= GRID_REL_TOL * dt_reg
        if regular_interval:
            n_steps = m_reg
        else:
            n_steps = max(1, int(math.ceil(length / cap - COUNT_SLACK)))
        hk = length / n_steps
        for k in range(1, n_steps + 1):
            tk = tb if k == n_steps else ta + k * hk
            on_grid = regular_interval
            while t < tk:
                n_call += 1.0
                if n_call >= n_check:
                    n_used = n_call - n_grid
                    over, t_win, n_win0, n_next = _budget_check(cx, t, n_used, t_win, n_win0,
                                                                n_scan)
                    if over:
                        status = STATUS_STEP_BUDGET
                        break
                    n_check = n_call + (n_next - n_used)
                stats[ST_N_STEPS] += 1.0
                step = ScanStep(tk - t, cap, on_grid, reg, rot)
                if m.mode != 0.0:
                    end = _slip_step(cx, stats, fresh, step, m)
                else:
                    end = _stick_step(cx, stats, step, m)
                m = end.motion
                on_grid = end.on_grid
                tau = end.tau
                ph1 = _wrap(ph1 + w1 * tau)
                ph2 = _wrap(ph2 + w2 * tau)
                if end.kind != 0:
                    t = t + tau
                    fresh = True
                    n_events += 1
                    status = _log_event(rec, t_start + t, end.kind, m.x, n_events, max_events)
                    if status != STATUS_OK:
                        break
                    continue
                t = t + tau if end.halved else tk
                fresh = False
                if not (math.isfinite(m.x) and math.isfinite(m.v)):
                    status = STATUS_NONFINITE
                    break
            if status != STATUS_OK:
                break
        if status != STATUS_OK:
            break
        if recording(rec):
            _write_output(rec, j + 1, m.x, m.v, m.mode)
            rec.counts[1] = j + 2
            n_grid += max(0.0, n_steps - length / cap)
    stats[ST_DURATION] += t
    _end_call(S, cx, t_start + t, m.x, m.v, m.mode, Phases(ph1, ph2, m.tones))
    return status
