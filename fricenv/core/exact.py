"""The exact runner (Coulomb law): closed-form slip steps, exact stick."""

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
    STATUS_NONFINITE,
    STATUS_OK,
)
from .closed_form import (
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
from .constants import _STATUS_NEAR_RESONANCE, COUNT_SLACK, GRID_REL_TOL, MIN_SPLIT
from .contacts import _contact_outcome, _contact_time, _start_slope, _stick_outcome
from .context import _scan_cap, _setup_context
from .proofs import _extremum_matters, _monotone, _one_extremum_at_most, _sign_kept, _stick_held
from .recording import _log_event
from .roots import K_SLIP_H, K_SLIP_V, _extremum
from .state import _end_call, _note_v, _note_x
from .stats import _slip_stats
from .stick import _stick_exit_time
from .trig import _renorm, _sincos, _wrap
from .whole_interval import _whole_interval
from .workspace import (
    C_C1A,
    C_C2A,
    C_DV,
    C_DX,
    C_GDDD,
    C_LAM,
    C_P2,
    C_S1A,
    C_S2A,
    C_U1,
    C_U2,
    C_V,
    C_VDD_H,
    C_VDD_P,
    C_VDDD_H,
    C_VDDD_P,
    C_W1,
    C_W2,
    C_XA,
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
)


# Exact (closed-form) runner
# ----------------------------------------------------------------------------------------
@kernel(inline=True)
def _run_exact(P, S, t_span, out_t, stats, max_events, out_x, out_v, out_mode, ev_t, ev_kind,
               ev_x, counts, cx):
    """Advance S by t_span with the closed-form solver; see ``advance``. Changes nothing
    and returns _STATUS_NEAR_RESONANCE when a tone is too close to resonance for it.

    A stats-only call that reads no extrema is first tried as one whole-call step when
    the scan would split it into several steps, or when it starts stuck (the stick proof
    is cheaper than a scan step). A slip call the scan covers in one step gains nothing
    from it: the (v - V)^2 constants a retuned tone needs cost more than that step.
    Otherwise, or when its proof fails, the scan runs. Kept small and
    inlined, so a whole-call step never pays the call into the scan's large function.
    """
    _setup_context(P, cx)
    if cx[W_T_KEY + T_NEAR_RES] != 0.0 or cx[W_T_KEY2 + T_NEAR_RES] != 0.0:
        return _STATUS_NEAR_RESONANCE
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
    cap = _scan_cap(P, cx[W_SKIP_EXTREMA] == 1.0)
    if (out_t is None and cx[W_SKIP_EXTREMA] == 1.0 and (t_span > cap or S[S_MODE] == 0.0)
            and _whole_interval(cx, S, t_span, stats, c1, s1, c2, s2)):
        return STATUS_OK
    return _scan_exact(S, t_span, out_t, stats, max_events, out_x, out_v, out_mode, ev_t,
                       ev_kind, ev_x, counts, cx, cap, c1, s1, c2, s2)

@kernel
def _scan_exact(S, t_span, out_t, stats, max_events, out_x, out_v, out_mode, ev_t, ev_kind,
                ev_x, counts, cx, cap, c1, s1, c2, s2):
    """The closed-form scan of ``_run_exact``, from its context (``cx``), the scan cap and
    the tones' cos/sin at the start.

    Steps are aligned with the output grid (``out_t``, or the single interval [t, t +
    t_span] when it is None), each output interval split into equal scan steps whose
    transition constants are computed once, so recording costs nothing extra.
    """
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    V = cx[C_V]
    lam = cx[C_LAM]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    # Time runs from 0 inside the call (see _run_event); S[S_T] is only written at the end.
    t_start = S[S_T]
    t_stop = t_span
    origin = out_t[0] if out_t is not None else 0.0
    n_int = 1
    dt_reg = t_span
    if out_t is not None:
        n_int = out_t.shape[0] - 1
        dt_reg = out_t[1] - out_t[0] if n_int > 0 else t_span
    m_reg = max(1, int(math.ceil(dt_reg / cap - COUNT_SLACK)))
    h_reg = dt_reg / m_reg
    # each piece is recomputed only when its own key changed (an agent retuning nu
    # invalidates the second tone's rotation, not the rest)
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
    r11, r12, r21, r22 = cx[W_R11], cx[W_R12], cx[W_R21], cx[W_R22]
    rc1, rs1, rc2, rs2 = cx[W_RC1], cx[W_RS1], cx[W_RC2], cx[W_RS2]

    x = S[S_X]
    v = S[S_V]
    mode = S[S_MODE]
    t = 0.0
    n_events = 0
    status = STATUS_OK
    fresh = True  # the current phase starts on a switching surface (or at the call start)
    _note_v(stats, v)
    _note_x(stats, x)
    if out_x is not None:
        out_x[0] = x
        out_v[0] = v
        out_mode[0] = mode
    # acceleration at the step start (slip), carried from step to step
    acc = 0.0
    if mode != 0.0:
        acc = -lam * v - x - mode * cx[C_XFK] + cx[C_U1] * c1 + cx[C_U2] * c2
    for j in range(n_int):
        ta = out_t[j] - origin if out_t is not None else 0.0
        tb = t_stop if j == n_int - 1 else (out_t[j + 1] - origin if out_t is not None
                                            else t_stop)
        length = tb - ta
        if length <= 0.0:
            continue
        regular_interval = abs(length - dt_reg) <= GRID_REL_TOL * dt_reg
        if regular_interval:
            m = m_reg
        else:
            m = max(1, int(math.ceil(length / cap - COUNT_SLACK)))
        hk = length / m
        for k in range(1, m + 1):
            tk = tb if k == m else ta + k * hk
            on_grid = regular_interval
            while t < tk:
                L = tk - t
                full = True  # the step reaches tk (False once halved)
                stats[ST_N_STEPS] += 1.0
                if mode != 0.0:
                    # ---------------- slip step ----------------
                    _slip_start(cx, x, v, c1, s1, c2, s2, mode)
                    sd = mode
                    h0 = sd * (v - V)
                    d0 = _start_slope(cx, fresh, h0, sd * acc, x, v)
                    j0 = _jerk(cx, v, acc, s1, s2)
                    r_h = math.sqrt(cx[C_DX] * cx[C_DX] + cx[C_DV] * cx[C_DV])
                    vdd = cx[C_VDD_P] + cx[C_VDD_H] * r_h  # bounds |v''| on the step
                    vddd = cx[C_VDDD_P] + cx[C_VDDD_H] * r_h  # bounds |v'''|
                    v_mid = 0.0  # off the grid: from the end's evaluation
                    while True:
                        if on_grid:
                            nc1, ns1, nc2, ns2 = _rotate(cx, rc1, rs1, rc2, rs2)
                            nc1, ns1 = _renorm(nc1, ns1)
                            nc2, ns2 = _renorm(nc2, ns2)
                            x1, v1, a1, j1 = _slip_with(cx, L, r11, r12, r21, r22, nc1, ns1,
                                                        nc2, ns2)
                        else:
                            v_mid, x1, v1, a1, j1, nc1, ns1, nc2, ns2 = _slip_mid_and_end(cx,
                                                                                         L)
                        h1 = sd * (v1 - V)
                        d1 = sd * a1
                        if _one_extremum_at_most(h0, d0, h1, d1, sd * j0, sd * j1, L, vdd,
                                                 vddd, cap):
                            break
                        L *= 0.5
                        full = False
                        on_grid = False
                    t_ext = -1.0
                    v_ext = 0.0
                    h_ext = 0.0
                    q_ext = 0.0
                    # a caller that reads no extrema needs v's extremum only to tell whether
                    # and where h first reaches 0: not when h changes sign over the step, as
                    # h (one extremum at most) then crosses 0 once, bracketed by the step
                    crossing = h0 > 0.0 and h1 < 0.0 and cx[W_SKIP_EXTREMA] == 1.0
                    if acc * a1 < 0.0 and not crossing and _extremum_matters(
                            cx, stats, sd, v, v1, acc, a1, L, V, vdd):
                        # third derivative of v: -lam v'' - v' + g''
                        _, _, gdd0 = _forcing(cx, c1, s1, c2, s2)
                        _, _, gdd1 = _forcing(cx, nc1, ns1, nc2, ns2)
                        t_ext = _extremum(cx, K_SLIP_V, 0.0, L, acc, a1, j0, j1,
                                          gdd0 - lam * j0 - acc, gdd1 - lam * j1 - a1)
                        _, v_ext, _, j_ext = _slip_at(cx, t_ext)
                        h_ext = sd * (v_ext - V)
                        q_ext = sd * j_ext
                    te = _contact_time(cx, K_SLIP_H, L, h0, d0, sd * j0, h1, d1, sd * j1, t_ext,
                                       h_ext, q_ext)
                    if te >= 0.0:
                        v_mid, xe, _, ae, je, ec1, es1, ec2, es2 = _slip_mid_and_end(cx, te)
                        _slip_stats(cx, K_SLIP_V, stats, te, t_ext, v_ext, v, acc, j0, V, ae,
                                    je, xe, v_mid, V)
                        new_mode, kind = _contact_outcome(cx, stats, xe, ec1, es1, ec2, es2, sd)
                        ph1 = _wrap(ph1 + w1 * te)
                        ph2 = _wrap(ph2 + w2 * te)
                        t = t + te
                        x = xe
                        v = V
                        c1, s1, c2, s2 = ec1, es1, ec2, es2
                        mode = new_mode
                        acc = 0.0
                        if mode != 0.0:
                            acc = (-lam * v - x - mode * cx[C_XFK] + cx[C_U1] * c1
                                   + cx[C_U2] * c2)
                        fresh = True
                        on_grid = False
                        n_events += 1
                        status = _log_event(ev_t, ev_kind, ev_x, counts, t_start + t, kind, x,
                                            n_events, max_events)
                        if status != STATUS_OK:
                            break
                        continue
                    if on_grid:
                        mc1, ms1, mc2, ms2 = _rotate(cx, cx[W_MC1], cx[W_MS1], cx[W_MC2],
                                                     cx[W_MS2])
                        _, v_mid, _, _ = _slip_with(cx, 0.5 * L, cx[W_M11], cx[W_M12],
                                                    cx[W_M21], cx[W_M22], mc1, ms1, mc2, ms2)
                    _slip_stats(cx, K_SLIP_V, stats, L, t_ext, v_ext, v, acc, j0, v1, a1, j1,
                                x1, v_mid, V)
                    x = x1
                    # a slip state has sd (v - V) >= 0; v1 may be a few ulps short of V
                    # where _unresolved_return saw no contact
                    v = v1 if sd * (v1 - V) >= 0.0 else V
                    acc = a1
                    c1, s1, c2, s2 = nc1, ns1, nc2, ns2
                    ph1 = _wrap(ph1 + w1 * L)
                    ph2 = _wrap(ph2 + w2 * L)
                else:
                    # ---------------- stick step ----------------
                    cx[C_XA] = x
                    cx[C_C1A] = c1
                    cx[C_S1A] = s1
                    cx[C_C2A] = c2
                    cx[C_S2A] = s2
                    g0, gd0, gdd0 = _forcing(cx, c1, s1, c2, s2)
                    f0 = -lam * V - x + g0
                    fd0 = -V + gd0
                    while True:
                        if on_grid:
                            nc1, ns1, nc2, ns2 = _rotate(cx, rc1, rs1, rc2, rs2)
                            nc1, ns1 = _renorm(nc1, ns1)
                            nc2, ns2 = _renorm(nc2, ns2)
                        else:
                            nc1, ns1, nc2, ns2 = _rotate_by(cx, L)
                        x1 = x + V * L
                        g1, gd1, gdd1 = _forcing(cx, nc1, ns1, nc2, ns2)
                        f1 = -lam * V - x1 + g1
                        fd1 = -V + gd1
                        held = _stick_held(cx, L, f0, fd0, f1, fd1)
                        m3 = cx[C_GDDD]  # bounds |f'''| = |g'''|
                        if (held or _monotone(fd0, gdd0, fd1, gdd1, L, m3)
                                or _sign_kept(gdd0, gdd1, L, m3) or L <= MIN_SPLIT * cap):
                            break
                        L *= 0.5
                        full = False
                        on_grid = False
                    te = -1.0 if held else _stick_exit_time(cx, L, f0, fd0, gdd0, f1, fd1,
                                                            gdd1)
                    if te >= 0.0:
                        xe = x + V * te
                        stats[ST_STICK_TIME] += te
                        _note_x(stats, xe)
                        _note_v(stats, V)
                        ec1, es1, ec2, es2 = _rotate_by(cx, te)
                        mode = _stick_outcome(cx, stats, xe, ec1, ec2)
                        ph1 = _wrap(ph1 + w1 * te)
                        ph2 = _wrap(ph2 + w2 * te)
                        t = t + te
                        x = xe
                        v = V
                        c1, s1, c2, s2 = ec1, es1, ec2, es2
                        acc = -lam * v - x - mode * cx[C_XFK] + cx[C_U1] * c1 + cx[C_U2] * c2
                        fresh = True
                        on_grid = False
                        n_events += 1
                        status = _log_event(ev_t, ev_kind, ev_x, counts, t_start + t, EVENT_SLIP,
                                            x, n_events, max_events)
                        if status != STATUS_OK:
                            break
                        continue
                    stats[ST_STICK_TIME] += L
                    _note_x(stats, x1)
                    _note_v(stats, V)
                    x = x1
                    c1, s1, c2, s2 = nc1, ns1, nc2, ns2
                    ph1 = _wrap(ph1 + w1 * L)
                    ph2 = _wrap(ph2 + w2 * L)
                t = tk if full else t + L
                fresh = False
                if not (math.isfinite(x) and math.isfinite(v)):
                    status = STATUS_NONFINITE
                    break
            if status != STATUS_OK:
                break
        if status != STATUS_OK:
            break
        if out_x is not None:
            out_x[j + 1] = x
            out_v[j + 1] = v
            out_mode[j + 1] = mode
            counts[1] = j + 2
    stats[ST_DURATION] += t
    _end_call(S, cx, t_start + t, x, v, mode, ph1, c1, s1, ph2, c2, s2)
    return status
