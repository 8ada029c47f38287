"""A whole stats-only call in one closed-form step, when a proof shows it holds no switch.

In slip, v is a damped oscillation plus two sinusoids, so over a call [0, T]:

* sd (v - V) is bounded below by the sum of each part's own lowest value: a tone's over
  the arc its phase sweeps (minus its amplitude if the arc passes its trough, else its
  lower end value), the damped part's from its ends and a bound on its curvature. When
  that sum stays above 0 there is no contact in the whole call, and one closed-form
  step covers it however many scan steps the tones' speed would otherwise take.
* the (v - V)^2 integral is exact: with each part written Re(a_k e^(z_k t)), a product of
  two parts integrates to T E((z_k + z_l) T) terms, E(s) = (e^s - 1) / s, whose values
  depend only on (lam, w1, w2, T) and are cached.

In stick, f = -lam V - x0 - V t + g(t) is bounded against +-xfs the same way.
Whatever is not proven goes to the scan. The damped part must oscillate (p^2 >= I_P2_MIN,
so 1 / p stays tame) and no tone may be resonant.
"""

import math

import numpy as np

from ..jit import kernel
from ..layout import (
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
)
from .closed_form import _homog, _particular
from .constants import E1_SERIES_MAX_R2, I_MARGIN, I_P2_MIN, TWO_PI
from .proofs import _stays_positive
from .state import Phases, Tones, _end_call, _note_v, _note_x
from .trig import _INV, _renorm, _sincos_long, _wrap
from .workspace import (
    C_KC1,
    C_KC2,
    C_KS1,
    C_KS2,
    C_LAM,
    C_P2,
    C_RES1,
    C_RES2,
    C_U1,
    C_U2,
    C_V,
    C_VDD_H,
    C_W1,
    C_W2,
    C_XFS,
    N_I_TONE,
    W_I_AMP1,
    W_I_AMP2,
    W_I_E12,
    W_I_EH,
    W_I_EHC,
    W_I_EHH,
    W_I_F11,
    W_I_KEY_E1,
    W_I_KEY_E2,
    W_I_KEY_LAM,
    W_I_KEY_T,
    W_I_KEY_W1,
    W_I_KEY_W2,
    W_I_P,
    W_I_TONE1,
    W_I_TONE2,
    W_SKIP_VR2,
)


@kernel
def _e1(s, es):
    """E(s) = (e^s - 1) / s from s and es = e^s (complex), in real arithmetic.

    Directly while |s| >= 0.01 (the rounding of e^s then costs at most ~100 ulps of E);
    below, the series sum s^k / (k + 1)!, whose 7 terms leave < 1e-16.
    """
    a = s.real
    b = s.imag
    r2 = a * a + b * b
    if r2 < E1_SERIES_MAX_R2:
        er = 1.0
        ei = 0.0
        for k in range(7, 1, -1):
            f = _INV[k]
            er, ei = 1.0 + (er * a - ei * b) * f, (er * b + ei * a) * f
        return complex(er, ei)
    nr = es.real - 1.0
    ni = es.imag
    inv = 1.0 / r2
    return complex((nr * a + ni * b) * inv, (ni * a - nr * b) * inv)

@kernel
def _cget(cx, k):
    return complex(cx[k], cx[k + 1])

@kernel
def _cset(cx, k, z):
    cx[k] = z.real
    cx[k + 1] = z.imag

@kernel
def _interval_constants(cx, T, lam, p2):
    """The whole-call transition and rotations for span T, each recomputed only when its
    own key changed (retuning a tone redoes that tone's rotation alone)."""
    if not (cx[W_I_KEY_LAM] == lam and cx[W_I_KEY_T] == T):
        cx[W_I_F11], cx[W_I_F11 + 1], cx[W_I_F11 + 2], cx[W_I_F11 + 3] = _homog(T, lam, p2)
        p = math.sqrt(p2)
        e = math.exp(-0.5 * lam * T)
        c, s = _sincos_long(p * T)
        eh = complex(e * c, e * s)
        _cset(cx, W_I_EH, eh)
        _cset(cx, W_I_EHH, _e1(complex(-lam * T, 2.0 * p * T), eh * eh))
        cx[W_I_EHC] = _e1(complex(-lam * T, 0.0), complex(e * e, 0.0)).real
        cx[W_I_P] = p
        cx[W_I_KEY_LAM] = lam
        cx[W_I_KEY_T] = T
        for k in (W_I_KEY_W1, W_I_KEY_W2, W_I_KEY_E1, W_I_KEY_E2):
            cx[k] = np.nan
    for i in range(2):
        w = cx[C_W1 + i]
        if cx[W_I_KEY_W1 + i] != w:
            hc, hs = _sincos_long(0.5 * w * T)
            base = W_I_TONE1 + i * N_I_TONE
            cx[base] = hc * hc - hs * hs
            cx[base + 1] = 2.0 * hs * hc
            cx[base + 2] = hc
            cx[base + 3] = hs
            cx[W_I_KEY_W1 + i] = w

@kernel
def _interval_e(cx, T):
    """The E values of the (v - V)^2 integral involving the tones (after
    ``_interval_constants``), recomputed for a retuned tone only."""
    e1 = cx[W_I_KEY_E1] != cx[C_W1]
    e2 = cx[W_I_KEY_E2] != cx[C_W2]
    if not (e1 or e2):
        return
    eh = _cget(cx, W_I_EH)
    zt = complex(-0.5 * cx[C_LAM] * T, cx[W_I_P] * T)
    r1 = _cget(cx, W_I_TONE1)
    r2 = _cget(cx, W_I_TONE2)
    w1t = cx[C_W1] * T
    w2t = cx[C_W2] * T
    for i in range(2):
        if (e1, e2)[i]:
            base = W_I_TONE1 + i * N_I_TONE
            rot = (r1, r2)[i]
            wt = complex(0.0, (w1t, w2t)[i])
            _cset(cx, base + 4, _e1(2.0 * wt, rot * rot))
            _cset(cx, base + 6, _e1(zt + wt, eh * rot))
            _cset(cx, base + 8, _e1(zt - wt, eh * rot.conjugate()))
    _cset(cx, W_I_E12, _e1(complex(0.0, w1t + w2t), r1 * r2))
    _cset(cx, W_I_E12 + 2, _e1(complex(0.0, w1t - w2t), r1 * r2.conjugate()))
    cx[W_I_KEY_E1] = cx[C_W1]
    cx[W_I_KEY_E2] = cx[C_W2]

@kernel
def _arc_passes_zero(c0, s0, cm, sm, c1, s1, alpha, eps):
    """Does the counter-clockwise arc of length alpha >= 0 from direction (c0, s0) through
    (cm, sm) (its midpoint) to (c1, s1) pass the angle 0? Borderline cases, within eps
    (rounding of the directions' components), count as yes.

    An arc of at most pi passes 0 exactly when it starts at sin <= 0 and ends at sin >= 0;
    a longer one is checked as its two halves.
    """
    if alpha >= TWO_PI:
        return True
    if alpha > math.pi:
        return (s0 <= eps and sm >= -eps) or (sm <= eps and s1 >= -eps)
    return s0 <= eps and s1 >= -eps

@kernel
def _lowest(amp, y0, y1, c0, s0, cm, sm, c1, s1, alpha):
    """Lowest value over the call of a sinusoid amp cos(psi) whose direction amp (cos psi,
    sin psi) sweeps the arc alpha from (c0, s0) through (cm, sm) to (c1, s1), with end
    values y0, y1: -amp if the arc passes the trough psi = pi, else the lower end (cos has
    no other minimum)."""
    if _arc_passes_zero(-c0, -s0, -cm, -sm, -c1, -s1, alpha, I_MARGIN * amp):
        return -amp
    return min(y0, y1)

@kernel
def _tone_dir(w, kc, ks, c, s):
    """Direction of a tone's particular velocity w (ks cos phi - kc sin phi): its value and
    the quadrature component."""
    return w * (ks * c - kc * s), w * (ks * s + kc * c)

@kernel
def _whole_interval(cx, S, T, stats, c1, s1, c2, s2):
    """Advance S over the whole call [t, t + T] in one closed-form step when a proof shows
    it holds no switch (see the section comment); False leaves everything untouched."""
    lam = cx[C_LAM]
    p2 = cx[C_P2]
    u1 = cx[C_U1]
    u2 = cx[C_U2]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    if not (p2 >= I_P2_MIN and cx[C_RES1] == 0.0 and cx[C_RES2] == 0.0 and w1 >= 0.0
            and w2 >= 0.0 and u1 >= 0.0 and u2 >= 0.0 and T > 0.0):
        return False
    _interval_constants(cx, T, lam, p2)
    t1 = W_I_TONE1
    t2 = W_I_TONE2
    nc1, ns1 = _renorm(c1 * cx[t1] - s1 * cx[t1 + 1], s1 * cx[t1] + c1 * cx[t1 + 1])
    nc2, ns2 = _renorm(c2 * cx[t2] - s2 * cx[t2 + 1], s2 * cx[t2] + c2 * cx[t2 + 1])
    mc1 = c1 * cx[t1 + 2] - s1 * cx[t1 + 3]
    ms1 = s1 * cx[t1 + 2] + c1 * cx[t1 + 3]
    mc2 = c2 * cx[t2 + 2] - s2 * cx[t2 + 3]
    ms2 = s2 * cx[t2 + 2] + c2 * cx[t2 + 3]
    arc1 = w1 * T
    arc2 = w2 * T
    V = cx[C_V]
    x = S[S_X]
    v = S[S_V]
    sd = S[S_MODE]
    if sd == 0.0:
        lin0 = -lam * V - x
        lin1 = lin0 - V * T
        top = max(lin0, lin1) - _lowest(u1, -u1 * c1, -u1 * nc1, -c1, -s1, -mc1, -ms1, -nc1,
                                        -ns1, arc1) - _lowest(
            u2, -u2 * c2, -u2 * nc2, -c2, -s2, -mc2, -ms2, -nc2, -ns2, arc2)
        bottom = min(lin0, lin1) + _lowest(u1, u1 * c1, u1 * nc1, c1, s1, mc1, ms1, nc1, ns1,
                                           arc1) + _lowest(
            u2, u2 * c2, u2 * nc2, c2, s2, mc2, ms2, nc2, ns2, arc2)
        xfs = cx[C_XFS]
        margin = I_MARGIN * (abs(lin0) + abs(lin1) + u1 + u2 + xfs)
        if not (top < xfs - margin and bottom > margin - xfs):
            return False
        x1 = x + V * T
        v1 = v
        stats[ST_STICK_TIME] += T
    else:
        kc1 = cx[C_KC1]
        ks1 = cx[C_KS1]
        kc2 = cx[C_KC2]
        ks2 = cx[C_KS2]
        xp0, vp0 = _particular(cx, 0.0, c1, s1, c2, s2, sd)
        xp1, vp1 = _particular(cx, T, nc1, ns1, nc2, ns2, sd)
        dx = x - xp0
        dv = v - vp0
        xh1 = cx[W_I_F11] * dx + cx[W_I_F11 + 1] * dv
        vh1 = cx[W_I_F11 + 2] * dx + cx[W_I_F11 + 3] * dv
        x1 = xp1 + xh1
        v1 = vp1 + vh1
        # the lowest value of sd * v_p over the call, tone by tone
        y0, q0 = _tone_dir(w1, kc1, ks1, c1, s1)
        ym, qm = _tone_dir(w1, kc1, ks1, mc1, ms1)
        y1, q1 = _tone_dir(w1, kc1, ks1, nc1, ns1)
        amp1 = cx[W_I_AMP1]
        low = _lowest(amp1, sd * y0, sd * y1, sd * y0, sd * q0, sd * ym, sd * qm, sd * y1,
                      sd * q1, arc1)
        y0, q0 = _tone_dir(w2, kc2, ks2, c2, s2)
        ym, qm = _tone_dir(w2, kc2, ks2, mc2, ms2)
        y1, q1 = _tone_dir(w2, kc2, ks2, nc2, ns2)
        amp2 = cx[W_I_AMP2]
        low += _lowest(amp2, sd * y0, sd * y1, sd * y0, sd * q0, sd * ym, sd * qm, sd * y1,
                       sd * q1, arc2)
        # ... plus sd * v_h, kept above -low + sd V by its ends and |v_h''| <= VDD_H r_h
        r_h = math.sqrt(dx * dx + dv * dv)
        floor = low - sd * V - I_MARGIN * (abs(V) + amp1 + amp2 + r_h)
        if not _stays_positive(sd * dv + floor, -sd * (lam * dv + dx), sd * vh1 + floor,
                               -sd * (lam * vh1 + xh1), T, cx[C_VDD_H] * r_h):
            return False
        if cx[W_SKIP_VR2] != 1.0:
            _interval_e(cx, T)
            # v - V = Re(ah e^(z_h t)) + Re(b1 e^(i w1 t)) + Re(b2 e^(i w2 t)) - V
            ah = complex(dv, (dx + 0.5 * lam * dv) / cx[W_I_P])
            b1 = complex(w1 * ks1, w1 * kc1) * complex(c1, s1)
            b2 = complex(w2 * ks2, w2 * kc2) * complex(c2, s2)
            sq = (ah * ah * _cget(cx, W_I_EHH)).real + (ah * ah.conjugate()).real * cx[W_I_EHC]
            sq += (b1 * b1 * _cget(cx, t1 + 4)).real + (b1 * b1.conjugate()).real
            sq += (b2 * b2 * _cget(cx, t2 + 4)).real + (b2 * b2.conjugate()).real
            cross = (ah * b1 * _cget(cx, t1 + 6) + ah * b1.conjugate() * _cget(cx, t1 + 8)
                     + ah * b2 * _cget(cx, t2 + 6) + ah * b2.conjugate() * _cget(cx, t2 + 8)
                     + b1 * b2 * _cget(cx, W_I_E12) + b1 * b2.conjugate() * _cget(
                         cx, W_I_E12 + 2)).real
            stats[ST_VR2_INT] += T * (0.5 * sq + cross + V * V) - 2.0 * V * (x1 - x)
    if not (math.isfinite(x1) and math.isfinite(v1)):
        return False
    stats[ST_N_STEPS] += 1.0
    stats[ST_DURATION] += T
    _note_v(stats, v)
    _note_x(stats, x)
    _note_v(stats, v1)
    _note_x(stats, x1)
    _end_call(S, cx, S[S_T] + T, x1, v1, sd, Phases(_wrap(S[S_PHI1] + w1 * T),
                                                    _wrap(S[S_PHI2] + w2 * T),
                                                    Tones(nc1, ns1, nc2, ns2)))
    return True
