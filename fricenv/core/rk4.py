"""The paper's scheme: fixed-step RK4 with sgn, kept as the baseline."""

import math

from ..friction import kernels as friction
from ..jit import kernel
from ..layout import (
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_STEPS,
    ST_VR2_INT,
    STATUS_NONFINITE,
    STATUS_OK,
)
from ..params import P_LAM, P_LAW, P_LAW_PARAMS, P_U1, P_U2, P_V, P_W1, P_W2, P_XFK, P_XFS
from .constants import COUNT_SLACK, GRID_REL_TOL
from .state import _note_v, _note_x
from .trig import _wrap


# The paper's scheme: fixed-step RK4 with sgn
# ----------------------------------------------------------------------------------------
@kernel
def _sgn_acc(P, lc, x, v, ph1, ph2):
    """Eq. 7 with the friction law's sgn(v - V) taken literally (0 at v = V); ``lc``: the
    law's constants."""
    vr = v - P[P_V]
    s = 1.0 if vr > 0.0 else (-1.0 if vr < 0.0 else 0.0)
    a = friction.sgn_accel(P[P_LAW], lc, -P[P_LAM] * v - x - P[P_XFK] * s, s, vr)
    return a + P[P_U1] * math.cos(ph1) + P[P_U2] * math.cos(ph2)

@kernel(allocates=True)
def run_rk4(P, S, t_span, dt, out_t, stats, out_x, out_v, out_mode):
    """The paper's scheme: classical RK4 on Eq. 7 with sgn(v - V), fixed step ``dt``.

    Kept as the baseline. It cannot represent sticking: v == V holds at no step, so the
    static level xfs never acts and the block chatters across v = V instead of riding the
    belt. ``mode`` reports sgn(v - V); ``ST_N_REVERSAL`` counts sign changes of v - V.
    Steps stay exactly ``dt`` (the last one is shortened to end at t_span); output times
    between steps are filled by cubic Hermite interpolation, which does not change the
    scheme.
    """
    w1 = P[P_W1]
    w2 = P[P_W2]
    V = P[P_V]
    lc = friction.prepare(P[P_LAW], P[P_LAW_PARAMS], P[P_LAW_PARAMS + 1], P[P_LAW_PARAMS + 2],
                          P[P_XFK], P[P_XFS])
    t0 = S[S_T]
    t = t0
    x = S[S_X]
    v = S[S_V]
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    n_out = out_t.shape[0]
    if n_out > 0:
        out_x[0] = x
        out_v[0] = v
        out_mode[0] = 1.0 if v > V else (-1.0 if v < V else 0.0)
    j = 1
    _note_v(stats, v)
    _note_x(stats, x)
    n = int(math.ceil(t_span / dt - COUNT_SLACK))
    k1v = _sgn_acc(P, lc, x, v, ph1, ph2)
    status = STATUS_OK
    for i in range(n):
        hh = dt if i < n - 1 else t_span - (n - 1) * dt
        k1x = v
        k2x = v + 0.5 * hh * k1v
        k2v = _sgn_acc(P, lc, x + 0.5 * hh * k1x, k2x, ph1 + 0.5 * hh * w1, ph2 + 0.5 * hh * w2)
        k3x = v + 0.5 * hh * k2v
        k3v = _sgn_acc(P, lc, x + 0.5 * hh * k2x, k3x, ph1 + 0.5 * hh * w1, ph2 + 0.5 * hh * w2)
        k4x = v + hh * k3v
        k4v = _sgn_acc(P, lc, x + hh * k3x, k4x, ph1 + hh * w1, ph2 + hh * w2)
        xn = x + hh / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
        vn = v + hh / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        ph1n = _wrap(ph1 + hh * w1)
        ph2n = _wrap(ph2 + hh * w2)
        an = _sgn_acc(P, lc, xn, vn, ph1n, ph2n)
        tn = t0 + (i + 1) * dt if i < n - 1 else t0 + t_span
        while j < n_out and out_t[j] <= tn + GRID_REL_TOL * max(1.0, abs(tn)):
            th = (out_t[j] - t) / hh
            h00 = (1.0 + 2.0 * th) * (1.0 - th) * (1.0 - th)
            h10 = th * (1.0 - th) * (1.0 - th)
            h01 = th * th * (3.0 - 2.0 * th)
            h11 = th * th * (th - 1.0)
            out_x[j] = h00 * x + h10 * hh * v + h01 * xn + h11 * hh * vn
            vj = h00 * v + h10 * hh * k1v + h01 * vn + h11 * hh * an
            out_v[j] = vj
            out_mode[j] = 1.0 if vj > V else (-1.0 if vj < V else 0.0)
            j += 1
        if (v - V) * (vn - V) < 0.0:
            stats[ST_N_REVERSAL] += 1.0
        vr0 = v - V
        vr1 = vn - V
        stats[ST_VR2_INT] += 0.5 * hh * (vr0 * vr0 + vr1 * vr1)
        x = xn
        v = vn
        k1v = an
        ph1 = ph1n
        ph2 = ph2n
        t = tn
        stats[ST_N_STEPS] += 1.0
        _note_v(stats, v)
        _note_x(stats, x)
        if not (math.isfinite(x) and math.isfinite(v)):
            status = STATUS_NONFINITE
            break
    stats[ST_DURATION] += t - t0
    S[S_T] = t
    S[S_X] = x
    S[S_V] = v
    S[S_MODE] = 1.0 if v > V else (-1.0 if v < V else 0.0)
    S[S_PHI1] = ph1
    S[S_PHI2] = ph2
    return status
