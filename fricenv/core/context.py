"""Per-call constants of a plant (``_setup_context``) and the scan step's cap."""

import math

import numpy as np

from ..friction import kernels as friction
from ..jit import kernel
from ..params import P_LAM, P_LAW, P_LAW_PARAMS, P_U1, P_U2, P_V, P_W1, P_W2, P_XFK, P_XFS
from .constants import _D2_MIN, DELTA_MAX, DELTA_WIDE, PHASE_PER_STEP, PHASE_PER_STEP_WIDE
from .workspace import (
    C_GDD,
    C_GDDD,
    C_KC1,
    C_KS1,
    C_LAM,
    C_LAW,
    C_LC,
    C_P2,
    C_RES1,
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
    C_XFS,
    N_T,
    T_GDD,
    T_GDDD,
    T_NEAR_RES,
    T_U,
    T_VDD_P,
    T_VDDD_P,
    T_W,
    W_I_AMP1,
    W_T_KEY,
    W_T_KEY2,
)


@kernel
def _tone_d2(w, lam):
    """1 - w^2, lam w and d2 = |1 - w^2 + i lam w|^2, the tone's response denominator."""
    re = 1.0 - w * w
    im = lam * w
    return re, im, re * re + im * im

@kernel
def closed_form_conditioned(P) -> bool:
    """False when a tone of P is too close to resonance for the closed form (see
    CLOSED_FORM_MAX_GAIN): the exact method then runs the event method."""
    for i in range(2):
        d2 = _tone_d2(P[P_W1 + i], P[P_LAM])[2]
        if P[P_U1 + i] != 0.0 and 0.0 < d2 < _D2_MIN:
            return False
    return True

@kernel(allocates=True)
def conditioned_rows(P_rows):
    """``closed_form_conditioned`` of each row of ``P_rows``."""
    ok = np.empty(P_rows.shape[0], np.bool_)
    for i in range(P_rows.shape[0]):
        ok[i] = closed_form_conditioned(P_rows[i])
    return ok


@kernel
def _setup_context(P, cx):
    """Constants of the run: particular-solution coefficients of each tone.

    A tone's constants are recomputed only when its (u, w) or lam changed since the last
    call on this workspace (a fresh one's NaN keys never match); the tones' shares of the
    bounds are summed in one fixed order, so the results never depend on the cache.
    """
    lam = P[P_LAM]
    same_lam = cx[C_LAM] == lam
    if not same_lam:  # (NaN in a fresh workspace) the damping's bounds, kept
        # x^2 + v^2 never grows in the homogeneous motion (its rate is -2 lam v^2), and
        # v_h'' = lam x_h + (lam^2 - 1) v_h, v_h''' = (1 - lam^2) x_h + (2 lam - lam^3) v_h.
        cx[C_VDD_H] = math.sqrt(lam * lam + (lam * lam - 1.0) ** 2)
        cx[C_VDDD_H] = math.sqrt((1.0 - lam * lam) ** 2 + (2.0 * lam - lam ** 3) ** 2)
    cx[C_LAM] = lam
    cx[C_V] = P[P_V]
    cx[C_XFK] = P[P_XFK]
    cx[C_XFS] = P[P_XFS]
    cx[C_U1] = P[P_U1]
    cx[C_U2] = P[P_U2]
    cx[C_W1] = P[P_W1]
    cx[C_W2] = P[P_W2]
    law = P[P_LAW]
    cx[C_LAW] = law
    lc = friction.prepare(law, P[P_LAW_PARAMS], P[P_LAW_PARAMS + 1], P[P_LAW_PARAMS + 2],
                          P[P_XFK], P[P_XFS])
    for i in range(4):
        cx[C_LC + i] = lc[i]
    cx[C_P2] = 1.0 - 0.25 * lam * lam
    for i in range(2):
        u = P[P_U1 + i]
        w = P[P_W1 + i]
        key = W_T_KEY + i * N_T
        if same_lam and cx[key + T_U] == u and cx[key + T_W] == w:
            continue
        re, im, d2 = _tone_d2(w, lam)
        res = 1.0 if (u != 0.0 and d2 == 0.0) else 0.0  # lam = 0 and w = 1: resonance
        cx[key + T_NEAR_RES] = 1.0 if (u != 0.0 and 0.0 < d2 < _D2_MIN) else 0.0
        kc = 0.0
        ks = 0.0
        if u != 0.0 and res == 0.0:
            kc = u * re / d2  # x_p = kc cos(phi) + ks sin(phi) = A cos(phi - theta)
            ks = u * im / d2
        cx[C_KC1 + 2 * i] = kc
        cx[C_KS1 + 2 * i] = ks
        cx[C_RES1 + i] = res
        if res != 0.0:
            # x_p = u tau sin(phi) / 2 (w = 1, tau from the step start, steps <= 1 long):
            # |v_p''| <= |u| (3 + tau) / 2, |v_p'''| <= |u| (4 + tau) / 2
            cx[key + T_VDD_P] = 2.0 * abs(u)
            cx[key + T_VDDD_P] = 2.5 * abs(u)
        else:
            amp = math.sqrt(kc * kc + ks * ks)
            cx[key + T_VDD_P] = amp * w * w * abs(w)
            cx[key + T_VDDD_P] = amp * w * w * w * w
            cx[W_I_AMP1 + i] = amp * abs(w)
        cx[key + T_GDD] = abs(u) * w * w
        cx[key + T_GDDD] = abs(u) * w * w * abs(w)
        cx[key + T_U] = u
        cx[key + T_W] = w
    cx[C_VDD_P] = cx[W_T_KEY + T_VDD_P] + cx[W_T_KEY2 + T_VDD_P]
    cx[C_VDDD_P] = cx[W_T_KEY + T_VDDD_P] + cx[W_T_KEY2 + T_VDDD_P]
    cx[C_GDD] = cx[W_T_KEY + T_GDD] + cx[W_T_KEY2 + T_GDD]
    cx[C_GDDD] = cx[W_T_KEY + T_GDDD] + cx[W_T_KEY2 + T_GDDD]

@kernel
def _scan_cap(P, wide):
    """Longest scan step: short against the fastest active tone and the damping rate."""
    base = DELTA_WIDE if wide else DELTA_MAX
    cap = base
    phase = PHASE_PER_STEP_WIDE if wide else PHASE_PER_STEP
    # one division, for the fastest tone (rounding is monotone, so it is the smallest
    # of the tones' own caps): every call starts here, and divisions are slow
    w_max = 0.0
    for i in range(2):
        if P[P_U1 + i] != 0.0:
            w_max = max(w_max, abs(P[P_W1 + i]))
    if w_max * cap > phase:
        cap = phase / w_max
    # Over-damped, the fast exponential's rate takes the place of the unit frequency of
    # under-damped motion: the step is held to the same base in units of 1 / rate (else the
    # (v - V)^2 quadrature's error, ~ (rate h)^8, passed 1e-9 of the integral at lam ~ 2.3-5).
    lam = P[P_LAM]
    if lam > 2.0:
        rate = 0.5 * lam + math.sqrt(0.25 * lam * lam - 1.0)
        if rate * cap > base:
            cap = base / rate
    return cap

def most_scan_steps(P_rows: np.ndarray, spans: np.ndarray) -> tuple[float, int]:
    """The most scan steps any row needs to cover its span, and that row (the first if
    several tie): the floor of a run's cost, known before it starts.

    ``_scan_cap(P, False)`` in numpy, operation for operation (no fast-math, so the same
    bits), not a kernel: environments check their cost when they are built, and the first
    call of a kernel there cost more (loading it from numba's cache, about 0.4 s) than all
    the rest of ``gymnasium.make``. ``tests/test_core.py`` checks it against the kernel.
    """
    P = np.asarray(P_rows, dtype=np.float64)
    if P.shape[0] == 0:
        return 0.0, 0
    w = np.where(P[:, [P_U1, P_U1 + 1]] != 0.0, np.abs(P[:, [P_W1, P_W1 + 1]]), 0.0)
    w_max = np.maximum(w[:, 0], w[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        cap = np.where(w_max * DELTA_MAX > PHASE_PER_STEP, PHASE_PER_STEP / w_max, DELTA_MAX)
        lam = P[:, P_LAM]
        rate = 0.5 * lam + np.sqrt(0.25 * lam * lam - 1.0)
        cap = np.where((lam > 2.0) & (rate * cap > DELTA_MAX), DELTA_MAX / rate, cap)
    n = np.asarray(spans, dtype=np.float64) / cap
    n = np.where(n > 0.0, n, 0.0)  # (the kernel's loop passed over NaN and n <= 0)
    row = int(np.argmax(n))
    return float(n[row]), row
