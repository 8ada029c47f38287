"""Forward sensitivities of the event method: the tangent of a run, exact through every switch.

A tangent column is the derivative (dx/dp, dv/dp) of the state by one parameter p. In slip
it obeys the variational equation of the slip equation,

    dx' = dv,    dv' = -lam dv - dx + A'(w) (dv - dV) + (da/dp)(t),

with ``A(w)`` the law's speed-dependent acceleration, ``w = v - V`` and ``(da/dp)`` the
explicit derivative of the acceleration (forcing, damping, the law's levels and
parameters). Its coefficients are known along each Taylor slip step as series (the step's
own series of x, v and w, and the law's ``tangent_series``), so the tangent's Taylor
coefficients follow from a linear recurrence, at O(n^2) flops a column and step, and its
dense output is exact to the step's accuracy, as the state's is.

In stick x = x_a + V t and v = V, so dx/dp grows by dV/dp t and dv/dp = dV/dp. At each
switch the tangent jumps by the saltation condition: the switching time moves by
``dtau = -(dh/dp) / (dh/dt)`` (h the switching function: v - V at a contact, sd f - xfs at
break-away) and the tangent by ``(f- - f+) dtau``, the difference of the vector fields
before and after. Where dh/dt vanishes (a grazing contact, a tangential break-away) or the
outcome is a tie (|f| = xfs at a contact), the derivative does not exist: the run notes the
time and kind (``Tangent.flags``) and the tangent turns NaN from there on.

:mod:`fricenv.sensitivity` validates, seeds and allocates; ``docs/methods.md`` derives
the conditions.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..friction import kernels as friction
from ..jit import kernel
from ..layout import (
    EVENT_STICK,
    S_T,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STEP_BUDGET,
    STATUS_TOO_STIFF,
)
from .constants import PHASE_RESYNC_STEPS, SCAN_ALLOWANCE, TAYLOR_FIRST_STEP, TIME_REL_TOL
from .context import _scan_cap, _setup_context
from .event import (
    Bounds,
    Motion,
    _event_stick_step,
    _finish,
    _start_motion,
    _stiffness,
    _taylor_step,
)
from .recording import _log_event, _write_output
from .slip import _law, _set_phases
from .state import _note_v, _note_x
from .taylor import _dense_v, taylor_order
from .trig import _INV
from .workspace import (
    C_CP1,
    C_CP2,
    C_LAM,
    C_SP1,
    C_SP2,
    C_TL,
    C_TN,
    C_TV,
    C_TW,
    C_U1,
    C_U2,
    C_V,
    C_W1,
    C_W2,
    C_XFS,
    _budget_check,
)

#: What a column differentiates by: the derivative of each quantity the kernels read (a
#: column by ``eta`` has w1 = 1 and w2 = nu, one by ``u0`` u1 = u2 = 1, ...).
SEED_DTYPE = np.dtype([(name, "f8") for name in (
    "lam", "V", "xfk", "xfs", "u1", "u2", "w1", "w2", "law0", "law1", "law2", "x0", "v0")])
#: Kinds of the points where the derivative does not exist (``Tangent.flags``).
FLAG_GRAZING = 1  # slip touches v = V with v' = 0
FLAG_TANGENT_BREAKAWAY = 2  # |f| reaches xfs in stick with f' = 0
FLAG_TIE = 3  # slip reaches v = V with |f| = xfs: stick or reversal is undecided
FLAG_NAMES = {FLAG_GRAZING: "grazing", FLAG_TANGENT_BREAKAWAY: "tangent break-away",
              FLAG_TIE: "stick/reversal tie"}
#: A switch is flagged where it would vanish (or change outcome) when h moves by less than
#: this share of the forces' scale: a contact whose crossing depth h'^2 / (2 |h''|) (how
#: far past the surface the motion would go) is that small, or a stick/reversal decision
#: that close to |f| = xfs. The derivative there holds only for parameter changes of that
#: relative size, below what any difference quotient or fit can use.
SINGULAR_REL = 1e-10
#: Rows of ``Tangent.law_rows``: the law's slope, its derivatives by xfk and xfs, and by
#: its three parameters. A run whose columns need fewer of the last three gets fewer rows
#: (``law_rows_needed``), and the law skips the series of the rows left out.
N_LAW_ROWS = 6
N_LEVEL_ROWS = 3


def law_rows_needed(seed: np.ndarray) -> int:
    """Rows of ``Tangent.law_rows`` the columns ``seed`` read: the first three, and the
    law parameters' up to the last one a column differentiates by."""
    law = [np.any(seed[f"law{i}"] != 0.0) for i in range(N_LAW_ROWS - N_LEVEL_ROWS)]
    return N_LEVEL_ROWS + (max(i + 1 for i, used in enumerate(law) if used) if any(law)
                           else 0)
#: Rows of ``Tangent.tones``: the series of cos and sin of each tone's phase (and one
#: more row of scratch, the (v - V)^2 integral's weights).
N_TONE_ROWS = 4


class Tangent(NamedTuple):
    """Inputs, outputs and scratch of a run with sensitivities (k columns).

    ``seed`` (k records of ``SEED_DTYPE``): what each column differentiates by. ``y`` (k, 2):
    the current (dx/dp, dv/dp), starting at the seeds' (x0, v0). ``out_dx``, ``out_dv``
    (n_out, k): the tangent at the output instants. ``ev_dt`` (event capacity, k): each
    switch's time derivative. ``d_stats`` (2, k): derivatives of the (v - V)^2 integral
    and of the stick time. ``flags`` (capacity, 2) and ``n_flags`` (1,): time and kind of
    the points without a derivative. ``law_rows``, ``tones``, ``ser`` (k, 2,
    SERIES_LEN): the series of a step.
    """

    seed: np.ndarray
    y: np.ndarray
    out_dx: np.ndarray
    out_dv: np.ndarray
    ev_dt: np.ndarray
    d_stats: np.ndarray
    flags: np.ndarray
    n_flags: np.ndarray
    law_rows: np.ndarray
    tones: np.ndarray
    ser: np.ndarray


@kernel
def _flag(tan, t, kind):
    """Note a point without a derivative at run time t; the tangent is NaN from there."""
    n = tan.n_flags[0]
    if n < tan.flags.shape[0]:
        tan.flags[n, 0] = t
        tan.flags[n, 1] = kind
    tan.n_flags[0] = n + 1
    for j in range(tan.y.shape[0]):
        tan.y[j, 0] = math.nan
        tan.y[j, 1] = math.nan


@kernel
def _scale(cx, x):
    """The size of the forces at displacement x, for the singularity tests."""
    return (abs(cx[C_LAM] * cx[C_V]) + abs(x) + cx[C_XFS] + abs(cx[C_U1]) + abs(cx[C_U2])
            + 1.0)


@kernel
def _dphase(s, t):
    """Derivatives of the tones' phases at run time t: (t dw1, t dw2)."""
    return t * s.w1, t * s.w2


@kernel
def _dforce(cx, s, t, dx, tones):
    """Derivative of f = -lam V - x + g(t) (every force but friction) by a column's
    parameter at run time t in stick, with dx/dp = dx; ``tones`` = the tones' (cos, sin,
    cos, sin) there."""
    c1, s1, c2, s2 = tones
    d1, d2 = _dphase(s, t)
    return (-s.lam * cx[C_V] - cx[C_LAM] * s.V - dx + s.u1 * c1 + s.u2 * c2
            - cx[C_U1] * s1 * d1 - cx[C_U2] * s2 * d2)


@kernel
def _step_series(cx, tan, sd, t0, tones, n):
    """The tangent's Taylor coefficients over the current slip step (from run time t0 and
    the tones' (cos, sin, cos, sin) at its start, the state's series in ``cx``) for every
    column, into ``tan.ser``."""
    law, lc = _law(cx)
    friction.tangent_series(law, lc, sd, cx, (C_TW, C_TL), tan.law_rows, n)
    tr = tan.tones
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    tr[0, 0], tr[1, 0], tr[2, 0], tr[3, 0] = tones
    for k in range(n):  # (cos + i sin)(phi + w t): times i w / (k + 1) an order
        r = _INV[k + 1]
        tr[0, k + 1] = -w1 * tr[1, k] * r
        tr[1, k + 1] = w1 * tr[0, k] * r
        tr[2, k + 1] = -w2 * tr[3, k] * r
        tr[3, k + 1] = w2 * tr[2, k] * r
    lam = cx[C_LAM]
    u1 = cx[C_U1]
    u2 = cx[C_U2]
    lr = tan.law_rows
    m = 0  # orders of the slope's series up to the last non-zero one (none: Coulomb)
    for k in range(n):
        if lr[0, k] != 0.0:
            m = k + 1
    for j in range(tan.y.shape[0]):
        s = tan.seed[j]
        ser = tan.ser[j]
        ser[0, 0] = tan.y[j, 0]
        ser[1, 0] = tan.y[j, 1]
        for k in range(n):
            # the explicit derivative of the acceleration, order k; the tones' phases
            # move by (t0 + t) dw_i
            e = (-s.lam * cx[C_TV + k] + s.xfk * lr[1, k] + s.xfs * lr[2, k]
                 + s.u1 * tr[0, k] + s.u2 * tr[2, k] - s.V * lr[0, k]
                 - t0 * (u1 * s.w1 * tr[1, k] + u2 * s.w2 * tr[3, k]))
            for r in range(N_LEVEL_ROWS, lr.shape[0]):  # (rows the seeds need)
                e += (s.law0, s.law1, s.law2)[r - N_LEVEL_ROWS] * lr[r, k]
            if k == 0:
                e -= sd * s.xfk
            else:
                e -= u1 * s.w1 * tr[1, k - 1] + u2 * s.w2 * tr[3, k - 1]
            conv = 0.0  # (A'(w) dv)_k
            for i in range(min(k + 1, m)):
                conv += lr[0, i] * ser[1, k - i]
            r = _INV[k + 1]
            ser[0, k + 1] = ser[1, k] * r
            ser[1, k + 1] = (-lam * ser[1, k] - ser[0, k] + conv + e) * r


@kernel
def _eval(ser, n, tau):
    """(dx/dp, dv/dp) of a column's step series at tau."""
    px = ser[0, n]
    pv = ser[1, n]
    for k in range(n - 1, -1, -1):
        px = px * tau + ser[0, k]
        pv = pv * tau + ser[1, k]
    return px, pv


@kernel
def _vr2_weights(cx, g, n, L):
    """Weights ``g[j] = sum_i w_i L^(i + j + 1) / (i + j + 1)`` of the step's series of w
    (length L): the (v - V)^2 integral's derivative over the step is then
    ``2 sum_j z_j g[j]`` for a column's series z of dv/dp - dV/dp, at O(n) a column."""
    lj = 1.0
    for j in range(n + 1):
        acc = 0.0
        li = L * lj
        for i in range(n + 1):
            acc += cx[C_TW + i] * li * _INV[i + j + 1]
            li *= L
        g[j] = acc
        lj *= L


@kernel
def _dvr2(ser, g, dV, n):
    """Derivative of the (v - V)^2 integral over the step: the integral of
    2 w (dv/dp - dV/dp), with the step's weights ``g`` (``_vr2_weights``)."""
    total = -dV * g[0]
    for j in range(n + 1):
        total += ser[1, j] * g[j]
    return 2.0 * total


@kernel
def _slip_tangent(cx, tan, rec, span, sd, tones):
    """Carry every column over the Taylor slip step just taken: ``span`` = (run time t0
    at its start, its length, first and past-last output instants it wrote, the output
    origin); ``sd`` its direction and ``tones`` the tones' cos/sin at its start."""
    t0, step_end, j0, j1, origin = span
    n = int(cx[C_TN])
    _step_series(cx, tan, sd, t0, tones, n)
    g = tan.tones[N_TONE_ROWS]
    _vr2_weights(cx, g, n, step_end)
    for j in range(tan.y.shape[0]):
        ser = tan.ser[j]
        for i in range(j0, j1):
            tau = min(max(rec.out_t[i] - origin - t0, 0.0), step_end)
            tan.out_dx[i, j], tan.out_dv[i, j] = _eval(ser, n, tau)
        tan.y[j, 0], tan.y[j, 1] = _eval(ser, n, step_end)
        tan.d_stats[0, j] += _dvr2(ser, g, tan.seed[j].V, n)


@kernel
def _stick_tangent(tan, rec, span):
    """Carry every column over the stick step just taken (``span`` as in
    ``_slip_tangent``): dx/dp grows by dV/dp t, dv/dp = dV/dp."""
    t0, step_end, j0, j1, origin = span
    for j in range(tan.y.shape[0]):
        dV = tan.seed[j].V
        for i in range(j0, j1):
            tau = min(max(rec.out_t[i] - origin - t0, 0.0), step_end)
            tan.out_dx[i, j] = tan.y[j, 0] + dV * tau
            tan.out_dv[i, j] = dV
        tan.y[j, 0] += dV * step_end
        tan.y[j, 1] = dV


@kernel
def _store_dt(tan, rec, j, dtau):
    """The derivative of the switch about to be logged (``rec.counts[0]``), column j."""
    i = rec.counts[0]
    if i < tan.ev_dt.shape[0]:
        tan.ev_dt[i, j] = dtau


@kernel
def _shallow(d1, d2, scale):
    """Whether a crossing with slope d1 and curvature d2 of the switching function is too
    shallow to differentiate (its depth d1^2 / (2 |d2|) under SINGULAR_REL of ``scale``)."""
    return d1 * d1 <= 2.0 * abs(d2) * SINGULAR_REL * scale


@kernel
def _contact_tangent(cx, tan, rec, kind, at, acc):
    """Saltation where slip reached v = V at ``at`` = (run time t, x, tones' phases ph1,
    ph2) (the step's series still in ``cx``; ``acc`` = (v'-, v''-, v'+): v' on either
    side and v'' before): the contact
    time moves by dtau = -(dv/dp - dV/dp) / v'-, and dv/dp jumps by (v'- - v'+) dtau (to
    dV/dp on sticking). Flags a grazing contact and a stick/reversal tie."""
    a_before, j_before, a_after = acc
    t, x, ph1, ph2 = at
    scale = _scale(cx, x)
    f = -cx[C_LAM] * cx[C_V] - x + cx[C_U1] * math.cos(ph1) + cx[C_U2] * math.cos(ph2)
    if _shallow(a_before, j_before, scale):
        _flag(tan, t, FLAG_GRAZING)
    elif abs(abs(f) - cx[C_XFS]) <= SINGULAR_REL * scale:
        _flag(tan, t, FLAG_TIE)
    for j in range(tan.y.shape[0]):
        dV = tan.seed[j].V
        dtau = -(tan.y[j, 1] - dV) / a_before
        _store_dt(tan, rec, j, dtau)
        if kind == EVENT_STICK:
            tan.y[j, 1] = dV
            tan.d_stats[1, j] -= dtau
        else:
            tan.y[j, 1] += (a_before - a_after) * dtau


@kernel
def _breakaway_tangent(cx, tan, rec, at, a_after, sd):
    """Saltation where stick ended at ``at`` = (run time t, x, tones' phases ph1, ph2),
    slipping in direction ``sd`` with v' = ``a_after``: h = sd f - xfs reached 0, so the break-away
    moves by dtau = -(dh/dp) / (dh/dt) and dv/dp jumps by -v'+ dtau. Flags a tangential
    break-away (f' = 0 there); a stick that the start state already violated ends at once,
    whatever the parameters (dtau = 0)."""
    t, x, ph1, ph2 = at
    c1 = math.cos(ph1)
    s1 = math.sin(ph1)
    c2 = math.cos(ph2)
    s2 = math.sin(ph2)
    f = -cx[C_LAM] * cx[C_V] - x + cx[C_U1] * c1 + cx[C_U2] * c2
    fd = -cx[C_V] - cx[C_U1] * cx[C_W1] * s1 - cx[C_U2] * cx[C_W2] * s2
    fdd = -cx[C_U1] * cx[C_W1] ** 2 * c1 - cx[C_U2] * cx[C_W2] ** 2 * c2
    scale = _scale(cx, x)
    past = sd * f - cx[C_XFS] > SINGULAR_REL * scale
    if not past and _shallow(fd, fdd, scale):
        _flag(tan, t, FLAG_TANGENT_BREAKAWAY)
    for j in range(tan.y.shape[0]):
        s = tan.seed[j]
        dh = sd * _dforce(cx, s, t, tan.y[j, 0], (c1, s1, c2, s2)) - s.xfs
        dtau = 0.0 if past else -dh / (sd * fd)
        _store_dt(tan, rec, j, dtau)
        tan.y[j, 1] -= a_after * dtau
        tan.d_stats[1, j] += dtau


@kernel
def _start_tangent(tan, rec, mode):
    """The tangent at the run's start: the seeds' (x0, v0); in stick v is held at V, so
    dv/dp = dV/dp. Written to the first output instant."""
    for j in range(tan.y.shape[0]):
        s = tan.seed[j]
        tan.y[j, 0] = s.x0
        tan.y[j, 1] = s.V if mode == 0.0 else s.v0
        tan.out_dx[0, j] = tan.y[j, 0]
        tan.out_dv[0, j] = tan.y[j, 1]


@kernel
def _end_outputs(tan, rec, j_out):
    """Output instants left at the very end (rounding of the last step): the last tangent."""
    for i in range(j_out, rec.out_t.shape[0]):
        for j in range(tan.y.shape[0]):
            tan.out_dx[i, j] = tan.y[j, 0]
            tan.out_dv[i, j] = tan.y[j, 1]


@kernel
def _run_tangent(P, S, t_span, settings, bufs, cx):
    """``_run_event`` of a recording run (Taylor steps in slip, exact stick) that carries
    the tangent along: see the module's docstring. ``settings`` = (rtol, atol, switches
    allowed); ``bufs`` = (the :class:`~fricenv.core.recording.Recording`, the
    :class:`Tangent`, the statistics). The state and statistics are those of a recording
    event run; the tangent's outputs go to the tangent."""
    rtol, atol, max_events = settings
    rec, tan, stats = bufs
    _setup_context(P, cx)
    cx[C_TN] = taylor_order(rtol)
    cap = _scan_cap(P, False)
    cap_slip = _scan_cap(P, True)
    t_start = S[S_T]
    origin = rec.out_t[0]
    lim = Bounds(t_span, cap, cap_slip, rtol, atol)
    m = _start_motion(cx, S)
    n_events = 0
    status = STATUS_OK
    fresh = True
    h = min(cap, TAYLOR_FIRST_STEP)
    phases_stale = True  # as _run_event, so that the state is the plain run's to the bit
    n_carried = 0
    n_call = 0.0
    n_check = 0.0
    t_win = 0.0
    n_win0 = 0.0
    n_scan = SCAN_ALLOWANCE / cap
    j_out = 1
    _write_output(rec, 0, m.x, m.v, m.mode)
    rec.counts[1] = 1
    _start_tangent(tan, rec, m.mode)
    _note_v(stats, m.v)
    _note_x(stats, m.x)
    while m.t < t_span and status == STATUS_OK:
        if t_span - m.t <= TIME_REL_TOL * max(1.0, abs(t_span)):
            m = Motion(t_span, m.x, m.v, m.acc, m.ph1, m.ph2, m.mode)
            break
        n_call += 1.0
        if n_call >= n_check:
            over, t_win, n_win0, n_check = _budget_check(cx, m.t, n_call, t_win, n_win0,
                                                         n_scan)
            if over:
                status = STATUS_STEP_BUDGET
                break
        t0 = m.t
        j0 = j_out
        if m.mode != 0.0:
            if phases_stale or n_carried >= PHASE_RESYNC_STEPS:
                _set_phases(cx, m.ph1, m.ph2)
                phases_stale = False
                n_carried = 0
            sd = m.mode
            tones = (cx[C_CP1], cx[C_SP1], cx[C_CP2], cx[C_SP2])
            too_stiff, kind, h, j_out, m = _taylor_step(
                cx, stats, rec, (j_out, origin), m, lim,
                (h, _stiffness(cx, sd, m.v - cx[C_V]), fresh))
            if too_stiff:
                status = STATUS_TOO_STIFF
                break
            _slip_tangent(cx, tan, rec, (t0, m.t - t0, j0, j_out, origin), sd, tones)
            if kind != 0:
                _, a_before, j_before = _dense_v(cx, m.t - t0)
                _contact_tangent(cx, tan, rec, kind, (m.t, m.x, m.ph1, m.ph2),
                                 (a_before, j_before, m.acc))
                phases_stale = True
            else:
                n_carried += 1
            fresh = kind != 0
        else:
            kind, j_out, m = _event_stick_step(cx, stats, rec, (j_out, origin), m, lim)
            _stick_tangent(tan, rec, (t0, m.t - t0, j0, j_out, origin))
            if kind != 0:
                _breakaway_tangent(cx, tan, rec, (m.t, m.x, m.ph1, m.ph2), m.acc, m.mode)
            fresh = kind != 0
            phases_stale = True
        if kind != 0:
            n_events += 1
            status = _log_event(rec, t_start + m.t, kind, m.x, n_events, max_events)
        if not (math.isfinite(m.x) and math.isfinite(m.v)):
            status = STATUS_NONFINITE
    if status == STATUS_OK:
        _end_outputs(tan, rec, j_out)
    _finish(S, stats, rec, (status, j_out, t_start), m)
    return status


@kernel(allocates=True, nogil=True)
def record_tangent(P, S, settings, bufs, work):
    """Record a run over [rec.out_t[0], rec.out_t[-1]] from ``S`` with the event method,
    carrying the tangent (``settings``, ``bufs`` = (rec, tangent, statistics) as in
    ``_run_tangent``); the status."""
    out_t = bufs[0].out_t
    return _run_tangent(P, S, out_t[out_t.shape[0] - 1] - out_t[0], settings, bufs, work)

