"""The event runner (any friction law): Taylor-series slip steps, exact stick."""

import math

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
    STIFF_HK,
    TAYLOR_FIRST_STEP,
    TIME_REL_TOL,
)
from .contacts import _contact_outcome, _contact_time, _start_slope, _stick_outcome
from .context import _scan_cap, _setup_context
from .proofs import _extremum_matters, _sign_kept, _stick_held, _v_one_extremum
from .recording import _log_event
from .roots import K_DENSE_H, K_DENSE_V, _extremum
from .rosenbrock import _ros4_step
from .slip import _acc, _carry, _end_phases, _rhs_acc, _set_phases
from .state import _note_v, _note_x
from .stats import _slip_extrema, _vr2_from_values
from .stick import _stick_exit_time
from .taylor import _dense_bounds, _dense_v, _dense_x, _taylor_coeffs, _taylor_vr2, taylor_order
from .trig import _sincos, _wrap
from .workspace import (
    C_B1,
    C_B3,
    C_C1A,
    C_C2A,
    C_CP1,
    C_CP2,
    C_GDDD,
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
)


@kernel
def _run_event(P, S, t_span, out_t, stats, max_events, rtol, atol, out_x, out_v, out_mode,
               ev_t, ev_kind, ev_x, counts, cx):
    """Advance S by t_span: Taylor-series steps in slip, exact stick; see ``advance``."""
    _setup_context(P, cx)
    cx[C_TN] = taylor_order(rtol)
    cap = _scan_cap(P, False)
    # Slip steps hold at most one extremum of v by proof (halved otherwise), so they may be
    # as long as the wide scan step; stick steps keep the scan step.
    cap_slip = _scan_cap(P, True)
    V = cx[C_V]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    # Time runs from 0 inside the call, and S[S_T] + t is formed only for events and the
    # end: thresholds relative to t (the end cut, the step floor) and rounding of t then
    # scale with the call's span, not with how long the run has been going (a call
    # continued from t = 1e12 was off by 1e-5 in x after 50 units of tau).
    t_start = S[S_T]
    t_stop = t_span
    origin = out_t[0] if out_t is not None else 0.0
    x = S[S_X]
    v = S[S_V]
    mode = S[S_MODE]
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    t = 0.0
    n_events = 0
    status = STATUS_OK
    fresh = True
    h = min(cap, TAYLOR_FIRST_STEP)  # the last Taylor step's natural length (stiffness test)
    h_ros = -1.0  # Rosenbrock step size while in a stiff stretch (-1: not in one)
    ros_backoff = 1.0  # Taylor steps to take before trying Rosenbrock again ...
    ros_skip = 0.0  # ... and those taken so far
    phases_stale = True
    n_carried = 0
    j_out = 1
    n_out = 0
    if out_t is not None:
        n_out = out_t.shape[0]
        out_x[0] = x
        out_v[0] = v
        out_mode[0] = mode
        counts[1] = 1
    _note_v(stats, v)
    _note_x(stats, x)
    acc = _rhs_acc(cx, mode, x, v, ph1, ph2) if mode != 0.0 else 0.0
    while t < t_stop and status == STATUS_OK:
        if t_stop - t <= TIME_REL_TOL * max(1.0, abs(t_stop)):
            t = t_stop
            break
        if mode != 0.0:
            # ---------------- one slip step ----------------
            if phases_stale or n_carried >= PHASE_RESYNC_STEPS:
                _set_phases(cx, ph1, ph2)  # resync the carried cos/sin with the angles
                phases_stale = False
                n_carried = 0
            sd = mode
            # Stiff stretch (the cubic law's slope |df/dv| past what an explicit step of
            # the tolerance's length can follow): on the stats-only path, a Rosenbrock
            # step, kept only where no switch, extremum or sign change of v needs a dense
            # output; anything else goes to the Taylor step.
            vr0 = v - V
            k_stiff = abs(cx[C_B1] - cx[C_LAM] - 3.0 * cx[C_B3] * vr0 * vr0)
            ros_taken = False
            if out_t is None and k_stiff * min(h, cap) >= STIFF_HK:
                h_stab = STIFF_HK / k_stiff  # about the Taylor step's stiff limit
                if not h_ros > 0.0:
                    h_ros = 2.0 * h_stab
                    ros_backoff = 1.0
                elif not h_ros > 1.5 * h_stab:
                    # Rejections shrank it to a Taylor step's length: try again after
                    # ros_backoff Taylor steps (doubling while it keeps failing), or one bad
                    # spot would leave the rest of the stretch on stability-bound steps.
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
                        ros_taken = (sd * (vr1 - V) > 0.0 and acc * ar > 0.0 and v * vr1 > 0.0
                                     and sd * vr0 > 0.0)
                        if ros_taken:
                            ros_backoff = 1.0
                            stats[ST_N_STEPS] += 1.0
                            _slip_extrema(cx, K_DENSE_V, stats, hr, -1.0, 0.0, v, vr1, xr)
                            if cx[W_SKIP_VR2] != 1.0:
                                stats[ST_VR2_INT] += _vr2_from_values(hr, v - V, vr1 - V,
                                                                      (xr - x) / hr - V)
                            t, x, v, acc, ph1, ph2 = _carry(cx, t, xr, vr1, ar, ph1, ph2, hr)
                            n_carried += 1
                            fresh = False
                        break
            else:
                h_ros = -1.0
            if not ros_taken:
                h = _taylor_coeffs(cx, sd, x, v, rtol, atol)
                a0 = cx[C_TV + 1]
                j0 = 2.0 * cx[C_TV + 2]
                # (a floor keeps time moving if the series blows up; the state then turns
                # non-finite and the run stops with STATUS_NONFINITE)
                h_floor = TIME_REL_TOL * max(1.0, abs(t))
                if h < h_floor and k_stiff * h_floor > 1.0:
                    # A floored step longer than the stiff time scale 1 / |df/dv| is neither
                    # accurate nor (from about 2.5) stable: its polynomial became a bogus
                    # contact (the block then rode the belt: 69 % off in x after one unit of
                    # tau, status OK) or an overflow (|v - V| ~ 1e7 with the cubic law, or
                    # stiff slip continued at a large t). The run stops instead.
                    status = STATUS_TOO_STIFF
                    break
                hstep = min(h if h > h_floor else h_floor, cap_slip, t_stop - t)
                while True:  # halved until v provably has one extremum at most
                    v1, a1, j1 = _dense_v(cx, hstep)
                    m2, m3 = _dense_bounds(cx, hstep)  # m2 serves the extremum test below
                    if _v_one_extremum(a0, j0, a1, j1, hstep, m3) or (
                            hstep <= MIN_SPLIT * cap_slip):
                        break
                    hstep *= 0.5
                x1 = _dense_x(cx, hstep)
                stats[ST_N_STEPS] += 1.0
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
                if a0 * a1 < 0.0 and _extremum_matters(cx, stats, sd, v, v1, a0, a1, hstep, V,
                                                       m2):
                    t_ext = _extremum(cx, K_DENSE_V, 0.0, hstep, a0, a1, j0, j1, math.nan,
                                      math.nan)
                    v_ext, _, j_ext = _dense_v(cx, t_ext)
                    h_ext = sd * (v_ext - V)
                    q_ext = sd * j_ext
                te = _contact_time(cx, K_DENSE_H, hstep, h0, d0, sd * j0, h1, d1, sd * j1, t_ext,
                                   h_ext, q_ext)
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
                if out_t is not None:  # outputs inside (t, t + step_end]
                    while j_out < n_out and out_t[j_out] - origin <= t + step_end + (
                            TIME_REL_TOL * max(1.0, abs(t))):
                        tau = min(max(out_t[j_out] - origin - t, 0.0), step_end)
                        if tau == step_end:
                            out_x[j_out] = x1
                            out_v[j_out] = v1
                        else:
                            out_x[j_out] = _dense_x(cx, tau)
                            out_v[j_out], _, _ = _dense_v(cx, tau)
                        out_mode[j_out] = mode
                        j_out += 1
                        counts[1] = j_out
                if step_end > 0.0:
                    _slip_extrema(cx, K_DENSE_V, stats, step_end, t_ext, v_ext, v, v1, x1)
                    if cx[W_SKIP_VR2] != 1.0:
                        stats[ST_VR2_INT] += _taylor_vr2(cx, step_end)
                if te >= 0.0:
                    pe1 = ph1 + w1 * te
                    pe2 = ph2 + w2 * te
                    xe = x1 if te > 0.0 else x
                    new_mode, kind = _contact_outcome(cx, stats, xe, math.cos(pe1), math.sin(pe1),
                                                      math.cos(pe2), math.sin(pe2), sd)
                    t = t + te
                    x = xe
                    v = V
                    ph1 = _wrap(pe1)
                    ph2 = _wrap(pe2)
                    phases_stale = True
                    mode = new_mode
                    acc = _rhs_acc(cx, mode, x, v, ph1, ph2) if mode != 0.0 else 0.0
                    fresh = True
                    n_events += 1
                    status = _log_event(ev_t, ev_kind, ev_x, counts, t_start + t, kind, x, n_events,
                                        max_events)
                else:
                    if sd * (v1 - V) < 0.0:  # a few ulps short (see _scan_exact)
                        v1 = V
                    ce1, se1 = _sincos(w1 * hstep)
                    ce2, se2 = _sincos(w2 * hstep)
                    c_end1, c_end2 = _end_phases(cx, cx[C_CP1], cx[C_SP1], cx[C_CP2],
                                                 cx[C_SP2], ce1, se1, ce2, se2)
                    # the equation's own acceleration at the end (the next series' v_1)
                    a_end = _acc(cx[C_LAM], V, sd * cx[C_XFK], cx[C_B1], cx[C_B3], 0.0, 0.0,
                                 x1, v1, 0.0, 0.0) + cx[C_U1] * c_end1 + cx[C_U2] * c_end2
                    t, x, v, acc, ph1, ph2 = _carry(cx, t, x1, v1, a_end, ph1, ph2, hstep)
                    n_carried += 1
                    fresh = False
        else:
            # ---------------- exact stick step ----------------
            L = min(cap, t_stop - t)
            stats[ST_N_STEPS] += 1.0
            cx[C_XA] = x
            cx[C_C1A] = math.cos(ph1)
            cx[C_S1A] = math.sin(ph1)
            cx[C_C2A] = math.cos(ph2)
            cx[C_S2A] = math.sin(ph2)
            _, f0, fd0, fdd0 = _stick_at(cx, 0.0)
            while True:  # halved until f provably has one extremum at most (see _run_exact)
                x1, f1, fd1, fdd1 = _stick_at(cx, L)
                held = _stick_held(cx, L, f0, fd0, f1, fd1)
                if held or _sign_kept(fdd0, fdd1, L, cx[C_GDDD]) or L <= MIN_SPLIT * cap:
                    break
                L *= 0.5
            te = -1.0 if held else _stick_exit_time(cx, L, f0, fd0, fdd0, f1, fd1, fdd1)
            step_end = L if te < 0.0 else te
            if out_t is not None:
                while j_out < n_out and out_t[j_out] - origin <= t + step_end + (
                        TIME_REL_TOL * max(1.0, abs(t))):
                    tau = min(max(out_t[j_out] - origin - t, 0.0), step_end)
                    out_x[j_out] = x + V * tau
                    out_v[j_out] = V
                    out_mode[j_out] = 0
                    j_out += 1
                    counts[1] = j_out
            stats[ST_STICK_TIME] += step_end
            _note_v(stats, V)
            _note_x(stats, x + V * step_end)
            ph1e = ph1 + w1 * step_end
            ph2e = ph2 + w2 * step_end
            x = x + V * step_end
            t = t + step_end
            ph1 = _wrap(ph1e)
            ph2 = _wrap(ph2e)
            fresh = False
            phases_stale = True
            if te >= 0.0:
                mode = _stick_outcome(cx, stats, x, math.cos(ph1e), math.cos(ph2e))
                acc = _rhs_acc(cx, mode, x, v, ph1, ph2)
                fresh = True
                n_events += 1
                status = _log_event(ev_t, ev_kind, ev_x, counts, t_start + t, EVENT_SLIP, x,
                                    n_events, max_events)
        if not (math.isfinite(x) and math.isfinite(v)):
            status = STATUS_NONFINITE
    # any output times left at the very end (rounding of the last step)
    if out_t is not None:
        while status == STATUS_OK and j_out < n_out:
            out_x[j_out] = x
            out_v[j_out] = v
            out_mode[j_out] = mode
            j_out += 1
            counts[1] = j_out
    stats[ST_DURATION] += t
    S[S_T] = t_start + t
    S[S_X] = x
    S[S_V] = v
    S[S_MODE] = mode
    S[S_PHI1] = ph1
    S[S_PHI2] = ph2
    return status
