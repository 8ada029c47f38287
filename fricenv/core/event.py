"""The event runner (any friction law): Taylor-series slip steps, exact stick.

The runner is a loop over steps: a slip step is a Rosenbrock step where the slip is stiff
and no dense output is needed (``_stiff_step``), else a Taylor step (``_taylor_step``:
series, trial length, contact search, outputs, statistics); a stick step is the exact one
of :mod:`fricenv.core.stick` (``_event_stick_step``).
"""

import math
from typing import NamedTuple

from ..friction import kernels as friction
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
    ST_VR2_INT,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STEP_BUDGET,
    STATUS_TOO_STIFF,
)
from .closed_form import _stick_at
from .constants import (
    MIN_SPLIT,
    PHASE_RESYNC_STEPS,
    ROS_BACKOFF_MAX,
    ROS_ERR_FLOOR,
    ROS_GROW_MAX,
    ROS_SAFETY,
    ROS_SHRINK_MIN,
    SCAN_ALLOWANCE,
    STIFF_HK,
    TAYLOR_FIRST_STEP,
    TIME_REL_TOL,
)
from .contacts import _contact_outcome, _contact_time, _start_slope, _stick_outcome
from .context import _scan_cap, _setup_context
from .proofs import _extremum_matters, _v_one_extremum
from .recording import _log_event, _write_output, recording
from .roots import K_DENSE_H, K_DENSE_V, _extremum_dense, _root_dense
from .rosenbrock import _ros4_step
from .slip import NO_FORCING, _acc, _carry, _end_phases, _law, _rhs_acc, _set_phases
from .state import _note_v, _note_x
from .stats import _slip_extrema, _vr2_from_values, _x_turn_dense
from .stick import _stick_exit_time, _stick_trial
from .taylor import _dense_bounds, _dense_v, _dense_x, _taylor_coeffs, _taylor_vr2, taylor_order
from .trig import _sincos, _wrap
from .workspace import (
    C_C1A,
    C_C2A,
    C_CP1,
    C_CP2,
    C_LAM,
    C_S1A,
    C_S2A,
    C_SD,
    C_SP1,
    C_SP2,
    C_TN,
    C_TV,
    C_U1,
    C_U2,
    C_V,
    C_W1,
    C_W2,
    C_XA,
    C_XFK,
    W_SKIP_VR2,
    _budget_check,
)


class Motion(NamedTuple):
    """The event runner's state between two steps: time since the call's start, x, v, the
    slip acceleration v' (0 in stick), the tones' phase angles and the mode (-1/+1: slip
    below/above the belt, 0: stick)."""

    t: float
    x: float
    v: float
    acc: float
    ph1: float
    ph2: float
    mode: float


class Bounds(NamedTuple):
    """What bounds every step of a call: its end ``t_stop`` (time since its start), the
    step caps of stick (``cap``) and of slip (``cap_slip``), and the tolerances."""

    t_stop: float
    cap: float
    cap_slip: float
    rtol: float
    atol: float


class Stiff(NamedTuple):
    """A stiff stretch's Rosenbrock state (``_stiff_step``): its step size ``h`` (-1: not
    in one), and after failures the Taylor steps to take before trying again
    (``backoff``) and those taken so far (``skip``)."""

    h: float
    backoff: float
    skip: float


@kernel
def _stiffness(cx, sd, vr):
    """|dv'/dv| in slip at vr = v - V: how fast slip relaxes, against the step length."""
    law, lc = _law(cx)
    return abs(friction.net_slope(law, lc, cx[C_LAM], sd, vr))


@kernel
def _output_due(rec, j_out, origin, t, step_end):
    """Is output instant ``j_out`` inside the step (t, t + step_end] (to the time
    resolution)? Never when not recording (``rec`` has no instant)."""
    return j_out < rec.out_t.shape[0] and rec.out_t[j_out] - origin <= t + step_end + (
        TIME_REL_TOL * max(1.0, abs(t)))


@kernel
def _output_tau(rec, j_out, origin, t, step_end):
    """Output instant ``j_out`` relative to the step's start t, within [0, step_end]."""
    return min(max(rec.out_t[j_out] - origin - t, 0.0), step_end)


@kernel
def _stiff_step(cx, stats, m, lim, h, ros):
    """A Rosenbrock slip step, where the slip is stiff (the cubic law's slope |df/dv|
    past what an explicit step of the tolerance's length can follow); stats-only calls.

    The step is kept only where no switch, extremum or sign change of v needs a dense
    output; anything else goes to the Taylor step (``taken`` False). From the
    :class:`Motion` ``m`` (slip direction ``m.mode``) within :class:`Bounds` ``lim``, ``h``
    the last Taylor step's natural length; carries the stiff stretch's :class:`Stiff`
    state ``ros``. Returns (taken, k_stiff = |df/dv|, the motion, the stiff state).
    """
    t, x, v, acc, ph1, ph2, sd = m
    t_stop, cap = lim.t_stop, lim.cap
    rtol, atol = lim.rtol, lim.atol
    h_ros, ros_backoff, ros_skip = ros
    V = cx[C_V]
    vr0 = v - V
    k_stiff = _stiffness(cx, sd, vr0)
    taken = False
    if not k_stiff * min(h, cap) >= STIFF_HK:
        return taken, k_stiff, m, Stiff(-1.0, ros_backoff, ros_skip)
    h_stab = STIFF_HK / k_stiff  # about the Taylor step's stiff limit
    if not h_ros > 0.0:
        h_ros = 2.0 * h_stab
        ros_backoff = 1.0
    elif not h_ros > 1.5 * h_stab:
        # Rejections shrank it to a Taylor step's length: try again after ros_backoff
        # Taylor steps (doubling while it keeps failing), or one bad spot would leave the
        # rest of the stretch on stability-bound steps.
        ros_skip += 1.0
        if ros_skip >= ros_backoff:
            ros_skip = 0.0
            ros_backoff = min(2.0 * ros_backoff, ROS_BACKOFF_MAX)
            h_ros = 2.0 * h_stab
    while h_ros > 1.5 * h_stab:
        hr = min(h_ros, cap, t_stop - t)
        xr, vr1, ar, ex, ev = _ros4_step(cx, sd, x, v, acc, hr)
        sx = atol + rtol * max(abs(x), abs(xr))
        sv = atol + rtol * max(abs(v), abs(vr1))
        err_r = 0.5 * ((ex / sx) ** 2 + (ev / sv) ** 2)
        h_ros = hr * min(ROS_GROW_MAX, max(ROS_SHRINK_MIN, ROS_SAFETY * (
            err_r + ROS_ERR_FLOOR) ** -0.125))
        if err_r <= 1.0:
            taken = (sd * (vr1 - V) > 0.0 and acc * ar > 0.0 and v * vr1 > 0.0
                     and sd * vr0 > 0.0)
            if taken:
                ros_backoff = 1.0
                stats[ST_N_STEPS] += 1.0
                _slip_extrema(_x_turn_dense, cx, stats, hr, -1.0, 0.0, v, vr1, xr)
                if cx[W_SKIP_VR2] != 1.0:
                    stats[ST_VR2_INT] += _vr2_from_values(hr, v - V, vr1 - V,
                                                          (xr - x) / hr - V)
                t, x, v, acc, ph1, ph2 = _carry(cx, (t, ph1, ph2), (xr, vr1, ar), hr)
            break
    return taken, k_stiff, Motion(t, x, v, acc, ph1, ph2, sd), Stiff(h_ros, ros_backoff,
                                                                      ros_skip)


@kernel
def _taylor_trial(cx, t, t_stop, h, cap_slip, k_stiff):
    """Length of a Taylor slip step whose series is in ``cx``: its natural length ``h``
    (floored at the time resolution), halved until v provably has one extremum at most.

    Returns (hstep, too stiff: the floored step is longer than the stiff time scale, v, v',
    v'' at the end and the bound on |v''| over the step); hstep < 0 when too stiff.
    """
    a0 = cx[C_TV + 1]
    j0 = 2.0 * cx[C_TV + 2]
    # (a floor keeps time moving if the series blows up; the state then turns non-finite
    # and the run stops with STATUS_NONFINITE)
    h_floor = TIME_REL_TOL * max(1.0, abs(t))
    if h < h_floor and k_stiff * h_floor > 1.0:
        # A floored step longer than the stiff time scale 1 / |df/dv| is neither accurate
        # nor (from about 2.5) stable: its polynomial became a bogus contact (the block
        # then rode the belt: 69 % off in x after one unit of tau, status OK) or an
        # overflow (|v - V| ~ 1e7 with the cubic law, or stiff slip continued at a large
        # t). The run stops instead.
        return -1.0, 0.0, 0.0, 0.0, 0.0
    hstep = min(h if h > h_floor else h_floor, cap_slip, t_stop - t)
    while True:  # halved until v provably has one extremum at most
        v1, a1, j1 = _dense_v(cx, hstep)
        m2, m3 = _dense_bounds(cx, hstep)  # m2 serves the extremum test
        if _v_one_extremum(a0, j0, a1, j1, hstep, m3) or hstep <= MIN_SPLIT * cap_slip:
            break
        hstep *= 0.5
    return hstep, v1, a1, j1, m2


@kernel
def _taylor_contact(cx, stats, fresh, hstep, start, end):
    """Where the Taylor step [0, hstep] from ``start`` = (x, v, slip direction) first
    reaches v = V (``end`` = v, v', v'' at its end and the bound on |v''|): (te, -1 if
    never; t_ext, v_ext: v's interior extremum if searched, -1 otherwise)."""
    x, v, sd = start
    v1, a1, j1, m2 = end
    V = cx[C_V]
    a0 = cx[C_TV + 1]
    j0 = 2.0 * cx[C_TV + 2]
    cx[C_XA] = x
    cx[C_SD] = sd
    h0 = sd * (v - V)
    d0 = _start_slope(cx, fresh, h0, sd * a0, x, v)
    h1 = sd * (v1 - V)
    d1 = sd * a1
    t_ext = -1.0
    v_ext = 0.0
    h_ext = 0.0
    q_ext = 0.0
    if a0 * a1 < 0.0 and _extremum_matters(cx, stats, sd, v, v1, a0, a1, hstep, V, m2):
        t_ext = _extremum_dense(cx, K_DENSE_V, 0.0, hstep, a0, a1, j0, j1, math.nan, math.nan)
        v_ext, _, j_ext = _dense_v(cx, t_ext)
        h_ext = sd * (v_ext - V)
        q_ext = sd * j_ext
    te = _contact_time(_root_dense, cx, K_DENSE_H, hstep, (h0, d0, sd * j0),
                       (h1, d1, sd * j1), (t_ext, h_ext, q_ext))
    return te, t_ext, v_ext


@kernel
def _taylor_outputs(rec, out, t, step_end, end, cx):
    """Write the output instants inside the Taylor step (t, t + step_end] from its series
    (``out`` = (next output's index, the outputs' origin); ``end`` = x, v and the mode at
    the step's end); the next output's index."""
    j_out, origin = out
    x1, v1, mode = end
    while _output_due(rec, j_out, origin, t, step_end):
        tau = _output_tau(rec, j_out, origin, t, step_end)
        if tau == step_end:
            rec.out_x[j_out] = x1
            rec.out_v[j_out] = v1
        else:
            rec.out_x[j_out] = _dense_x(cx, tau)
            rec.out_v[j_out], _, _ = _dense_v(cx, tau)
        rec.out_mode[j_out] = mode
        j_out += 1
        rec.counts[1] = j_out
    return j_out


@kernel
def _taylor_step(cx, stats, rec, out, m, lim, trial):
    """One Taylor slip step from the :class:`Motion` ``m`` (direction ``m.mode``; the
    tones' cos/sin at its start in ``cx``) within :class:`Bounds` ``lim``, up to a contact
    if one comes first, with its outputs (``out`` = (next output's index, the outputs'
    origin)) and statistics. ``trial`` = (the last step's natural length, the stiffness
    |dv'/dv| at the start, whether the phase has just begun).

    Returns (too stiff, event kind (0: none), the series' natural step length, the next
    output's index, the motion at the step's end).
    """
    t, x, v, _, ph1, ph2, sd = m
    j_out, origin = out
    h, k_stiff, fresh = trial
    V = cx[C_V]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    h = _taylor_coeffs(cx, sd, x, v, lim.rtol, lim.atol)
    hstep, v1, a1, j1, m2 = _taylor_trial(cx, t, lim.t_stop, h, lim.cap_slip, k_stiff)
    if hstep < 0.0:
        return True, 0, h, j_out, Motion(t, x, v, 0.0, ph1, ph2, sd)
    x1 = _dense_x(cx, hstep)
    stats[ST_N_STEPS] += 1.0
    te, t_ext, v_ext = _taylor_contact(cx, stats, fresh, hstep, (x, v, sd), (v1, a1, j1, m2))
    if te > 0.0:
        step_end = te
        x1 = _dense_x(cx, te)
        v1 = V
        if not (0.0 <= t_ext <= te):
            t_ext = -1.0
    elif te == 0.0:
        step_end = 0.0
    else:
        step_end = hstep
    j_out = _taylor_outputs(rec, (j_out, origin), t, step_end, (x1, v1, sd), cx)
    if step_end > 0.0:
        _slip_extrema(_x_turn_dense, cx, stats, step_end, t_ext, v_ext, v, v1, x1)
        if cx[W_SKIP_VR2] != 1.0:
            stats[ST_VR2_INT] += _taylor_vr2(cx, step_end)
    if te >= 0.0:
        pe1 = ph1 + w1 * te
        pe2 = ph2 + w2 * te
        xe = x1 if te > 0.0 else x
        new_mode, kind = _contact_outcome(cx, stats, xe, math.cos(pe1), math.sin(pe1),
                                          math.cos(pe2), math.sin(pe2), sd)
        ph1 = _wrap(pe1)
        ph2 = _wrap(pe2)
        acc = _rhs_acc(cx, new_mode, xe, V, ph1, ph2) if new_mode != 0.0 else 0.0
        return False, kind, h, j_out, Motion(t + te, xe, V, acc, ph1, ph2, new_mode)
    if sd * (v1 - V) < 0.0:  # a few ulps short (see _scan_exact)
        v1 = V
    ce1, se1 = _sincos(w1 * hstep)
    ce2, se2 = _sincos(w2 * hstep)
    c_end1, c_end2 = _end_phases(cx, (cx[C_CP1], cx[C_SP1], cx[C_CP2], cx[C_SP2]),
                                 (ce1, se1, ce2, se2))
    # the equation's own acceleration at the end (the next series' v_1)
    law, lc = _law(cx)
    a_end = (_acc((cx[C_LAM], V, cx[C_XFK]), law, lc, sd, (x1, v1), NO_FORCING)
             + cx[C_U1] * c_end1 + cx[C_U2] * c_end2)
    t, x, v, acc, ph1, ph2 = _carry(cx, (t, ph1, ph2), (x1, v1, a_end), hstep)
    return False, 0, h, j_out, Motion(t, x, v, acc, ph1, ph2, sd)


@kernel
def _event_stick_step(cx, stats, rec, out, m, lim):
    """One exact stick step from the :class:`Motion` ``m`` within :class:`Bounds` ``lim``,
    up to the stick's end if it comes first, with its outputs (``out`` as in
    ``_taylor_step``) and statistics. Returns (event kind (0: none), the next output's
    index, the motion at the step's end)."""
    t, x, v, acc, ph1, ph2, mode = m
    j_out, origin = out
    V = cx[C_V]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    L = min(lim.cap, lim.t_stop - t)
    stats[ST_N_STEPS] += 1.0
    cx[C_XA] = x
    cx[C_C1A] = math.cos(ph1)
    cx[C_S1A] = math.sin(ph1)
    cx[C_C2A] = math.cos(ph2)
    cx[C_S2A] = math.sin(ph2)
    _, f0, fd0, fdd0 = _stick_at(cx, 0.0)
    L, _, _, held, _, f1, fd1, fdd1, _, _, _, _ = _stick_trial(
        cx, L, lim.cap, False, (0.0, 0.0, 0.0, 0.0), False, f0, fd0, fdd0)
    te = -1.0 if held else _stick_exit_time(cx, L, f0, fd0, fdd0, f1, fd1, fdd1)
    step_end = L if te < 0.0 else te
    while _output_due(rec, j_out, origin, t, step_end):
        tau = _output_tau(rec, j_out, origin, t, step_end)
        rec.out_x[j_out] = x + V * tau
        rec.out_v[j_out] = V
        rec.out_mode[j_out] = 0
        j_out += 1
        rec.counts[1] = j_out
    stats[ST_STICK_TIME] += step_end
    _note_v(stats, V)
    _note_x(stats, x + V * step_end)
    ph1e = ph1 + w1 * step_end
    ph2e = ph2 + w2 * step_end
    x = x + V * step_end
    t = t + step_end
    ph1 = _wrap(ph1e)
    ph2 = _wrap(ph2e)
    if te < 0.0:
        return 0, j_out, Motion(t, x, v, acc, ph1, ph2, mode)
    mode = _stick_outcome(cx, stats, x, math.cos(ph1e), math.cos(ph2e))
    return EVENT_SLIP, j_out, Motion(t, x, v, _rhs_acc(cx, mode, x, v, ph1, ph2), ph1, ph2,
                                     mode)


@kernel
def _run_event(P, S, t_span, stats, max_events, rtol, atol, rec, cx):
    """Advance S by t_span: Taylor-series steps in slip, exact stick; see ``advance``.

    ``rec``: a :class:`~fricenv.core.recording.Recording` to fill (empty: stats only,
    where stiff stretches may take Rosenbrock steps).
    """
    _setup_context(P, cx)
    cx[C_TN] = taylor_order(rtol)
    cap = _scan_cap(P, False)
    # Slip steps hold at most one extremum of v by proof (halved otherwise), so they may be
    # as long as the wide scan step; stick steps keep the scan step.
    cap_slip = _scan_cap(P, True)
    # Time runs from 0 inside the call, and S[S_T] + t is formed only for events and the
    # end: thresholds relative to t (the end cut, the step floor) and rounding of t then
    # scale with the call's span, not with how long the run has been going (a call
    # continued from t = 1e12 would be off by 1e-5 in x after 50 units of tau).
    t_start = S[S_T]
    lim = Bounds(t_span, cap, cap_slip, rtol, atol)
    origin = rec.out_t[0] if recording(rec) else 0.0
    m = _start_motion(cx, S)
    n_events = 0
    status = STATUS_OK
    fresh = True
    h = min(cap, TAYLOR_FIRST_STEP)  # the last Taylor step's natural length (stiffness test)
    ros = Stiff(-1.0, 1.0, 0.0)  # no stiff stretch yet
    phases_stale = True
    n_carried = 0
    n_call = 0.0  # steps so far, and the step budget's state (see _budget_check)
    n_check = 0.0
    t_win = 0.0
    n_win0 = 0.0
    n_scan = SCAN_ALLOWANCE / cap
    j_out = 1
    if recording(rec):
        _write_output(rec, 0, m.x, m.v, m.mode)
        rec.counts[1] = 1
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
        kind = 0
        if m.mode != 0.0:
            if phases_stale or n_carried >= PHASE_RESYNC_STEPS:
                _set_phases(cx, m.ph1, m.ph2)  # resync the carried cos/sin with the angles
                phases_stale = False
                n_carried = 0
            taken = False
            k_stiff = 0.0
            if not recording(rec):
                taken, k_stiff, m, ros = _stiff_step(cx, stats, m, lim, h, ros)
            else:
                k_stiff = _stiffness(cx, m.mode, m.v - cx[C_V])
                ros = Stiff(-1.0, ros.backoff, ros.skip)
            if taken:
                n_carried += 1
                fresh = False
            else:
                too_stiff, kind, h, j_out, m = _taylor_step(cx, stats, rec, (j_out, origin),
                                                            m, lim, (h, k_stiff, fresh))
                if too_stiff:
                    status = STATUS_TOO_STIFF
                    break
                if kind != 0:
                    phases_stale = True
                else:
                    n_carried += 1
                    fresh = False
        else:
            kind, j_out, m = _event_stick_step(cx, stats, rec, (j_out, origin), m, lim)
            fresh = False
            phases_stale = True
        if kind != 0:
            fresh = True
            n_events += 1
            status = _log_event(rec, t_start + m.t, kind, m.x, n_events, max_events)
        if not (math.isfinite(m.x) and math.isfinite(m.v)):
            status = STATUS_NONFINITE
    _finish(S, stats, rec, (status, j_out, t_start), m)
    return status


@kernel
def _start_motion(cx, S):
    """The :class:`Motion` a call starts from, the state vector ``S`` (time 0: the call's
    own clock)."""
    x = S[S_X]
    v = S[S_V]
    mode = S[S_MODE]
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    acc = _rhs_acc(cx, mode, x, v, ph1, ph2) if mode != 0.0 else 0.0
    return Motion(0.0, x, v, acc, ph1, ph2, mode)


@kernel
def _finish(S, stats, rec, end, m):
    """End a call at the :class:`Motion` ``m``: the output instants left by the last
    step's rounding, the duration, and the state written back to ``S``. ``end`` = (the
    call's status, the next output's index, its start time)."""
    status, j_out, t_start = end
    if recording(rec):
        while status == STATUS_OK and j_out < rec.out_t.shape[0]:
            _write_output(rec, j_out, m.x, m.v, m.mode)
            j_out += 1
            rec.counts[1] = j_out
    stats[ST_DURATION] += m.t
    S[S_T] = t_start + m.t
    S[S_X] = m.x
    S[S_V] = m.v
    S[S_MODE] = m.mode
    S[S_PHI1] = m.ph1
    S[S_PHI2] = m.ph2
