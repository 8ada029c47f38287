"""Numba kernels of the stick-slip oscillator (paper's Eq. 7).

Three integrators share one event logic:

* ``exact`` (Coulomb law, b1 = b3 = 0): each slip step is the closed-form solution of the
  linear slip equation (homogeneous transition matrix for any damping, including the
  critically damped and resonant cases, plus the particular response to each tone); each
  stick phase is exact. Only switching instants are found numerically, by bracketed
  Halley iteration on the closed form. A stats-only call that reads no extrema (an
  environment's control interval) is first tried as one closed-form step, taken when a
  bound on each part of the motion proves it switch-free; its (v - V)^2 integral is then
  exact too.
* ``event`` (any friction law): Taylor-series steps inside slip phases (the slip equation
  is polynomial, so the series' coefficients follow from a recurrence; order about
  -ln(rtol) / 2, step length from the decay of the last terms, Jorba & Zou 2005), exact
  stick phases. The series is the step's dense output: switches, extrema and output
  times are found on it, and the (v - V)^2 integral is exact on it. Stiff stretches of a
  stats-only run take L-stable Rosenbrock 4(3) steps where no dense output is needed.
* ``rk4``: the paper's fixed-step RK4 with ``sgn``, kept as the baseline. It cannot
  represent sticking.

Switches (slip -> stick, stick -> slip, reversal) are searched on every step: a sign
change at the ends, and an interior extremum located from the sign change of the
derivative. A step is halved until it provably holds at most one extremum (curvature
bounds: ``_one_extremum_at_most``, ``_v_one_extremum``, ``_sign_kept``); that is how
grazing contacts, where ``v`` touches ``V`` tangentially, are caught.

Public kernels (all ``@njit(cache=True)``, allocation-free in their step loops):
``reset_stats``, ``initial_state``, ``advance`` (stats only) and the recording runners used
by :mod:`fricenv.simulate`. Array layouts are in :mod:`fricenv.layout` and
:mod:`fricenv.params`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import (
    EVENT_REVERSAL,
    EVENT_SLIP,
    EVENT_STICK,
    METHOD_EXACT,
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_SLIP,
    ST_N_STEPS,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
    ST_VR2_INT,
    ST_X_MAX,
    ST_X_MIN,
    STATUS_BUFFER_FULL,
    STATUS_EVENT_CAP,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_TOO_STIFF,
)
from .params import P_B1, P_B3, P_LAM, P_U1, P_U2, P_V, P_W1, P_W2, P_XFK, P_XFS

# Kernels that never allocate are compiled with ``_nrt=False`` (numba's CPU target option
# that turns its reference-counting runtime off for that function). Otherwise every call
# that passes an array (or a view such as P[i]) does atomic incref/decref pairs on the
# array's shared counter: measured, that was ~40 % of a scan step, and with threads the
# counters of a batch's common parent array bounce between cores. The caller keeps every
# array alive for the duration of the call, so no count is needed. Only ``advance``,
# ``record`` and ``fresh_workspace``, which allocate, keep the runtime.
#
# Every kernel uses numba's ``error_model="numpy"``: a float division by zero gives an
# inf or a NaN, as in numpy, instead of raising ZeroDivisionError from deep inside a
# kernel. Subnormal data can make a Halley or Newton denominator exactly 0; the root
# searches then fall back to the secant point or to bisection, and a non-finite state
# ends a run with STATUS_NONFINITE. It also spares the zero test before every division.
TWO_PI = 2.0 * math.pi
# Scan steps must hold at most one extremum of v (or of f in stick): a tone's extrema are
# pi / omega apart, so half a radian per step leaves a wide margin (>= 12 steps a period).
DELTA_MAX = 0.5  # longest scan step in tau
PHASE_PER_STEP = 0.5  # longest scan step in radians of the fastest active tone
# A caller that reads no extrema (W_SKIP_EXTREMA) needs only the switches, which the curvature
# proofs guard on steps of any length (see _one_extremum_at_most), so its scan steps may be
# longer: a radian of the fastest tone keeps the (v - V)^2 quadrature within ~1e-6 V^2 tau.
DELTA_WIDE = 1.0
PHASE_PER_STEP_WIDE = 1.0
# Steps are halved until the proofs hold, at most down to this fraction of the scan step.
MIN_SPLIT = 1.0 / 1024.0
MAX_ROOT_ITER = 200
# The closed form writes x = x_p + H (x0 - x_p), and a tone's particular amplitude is
# |u| / sqrt(d2), d2 = (1 - w^2)^2 + (lam w)^2. Near resonance both terms are large and
# their sum loses digits: over tau = 60 at lam = 0, the max |x| error was 9e-13 at a gain
# 1 / sqrt(d2) of 500, 6e-11 at 5e3 and 1e-9 at 5e4 (and a gain of 1e15, one ulp off
# resonance, made rounding noise look like chattering). Past this gain the exact method
# hands the call to the event method; exact resonance (d2 = 0) keeps its own closed form.
CLOSED_FORM_MAX_GAIN = 1e3
_D2_MIN = 1.0 / (CLOSED_FORM_MAX_GAIN * CLOSED_FORM_MAX_GAIN)
# Returned by the closed-form runner when a tone is too close to resonance (never leaves
# ``advance_ws`` / ``record``, which then run the event method).
_STATUS_NEAR_RESONANCE = -1
EVENT_REL_TOL = 1e-15  # switching instants: to rounding (a few ulps of the step time)
GRAZE_ULPS = 8.0  # a velocity extremum this many ulps of V short of V still touches it
# ... and this much of a value's terms is its rounding (contacts, ties with x_fs)
GRAZE_REL = GRAZE_ULPS * 2.220446049250313e-16
# An extremum's value is insensitive to its position (error ~ f'' dt^2), so 1e-9 in time
# already gives the value to rounding.
EXTREMUM_REL_TOL = 1e-9

# Slots of the per-call context array ``cx`` (one small allocation per call).
C_LAM, C_V, C_XFK, C_XFS, C_U1, C_U2, C_W1, C_W2, C_P2 = range(9)
C_KC1, C_KS1, C_KC2, C_KS2, C_RES1, C_RES2, C_B1, C_B3 = range(9, 17)
C_XA, C_VA, C_C1A, C_S1A, C_C2A, C_S2A, C_SD, C_DX, C_DV = range(17, 26)
C_TN = 26  # order of the current Taylor slip step (its coefficients: C_TX, C_TV, C_TW)
C_CP1, C_SP1, C_CP2, C_SP2 = 27, 28, 29, 30  # tones' cos/sin at the step start, carried
C_CE1, C_SE1, C_CE2, C_SE2 = 31, 32, 33, 34  # ... and at the end of the last slip step
# Cache kept across calls when the caller passes the same workspace (``advance_ws``): the
# regular scan step's transition constants, keyed on (lam, w1, w2, h), and each tone's
# cos/sin, keyed on the phase angle last written to S. Keys start as NaN (never equal).
W_KEY_LAM, W_KEY_W1, W_KEY_W2, W_KEY_H = 35, 36, 37, 38
W_R11, W_R12, W_R21, W_R22, W_RC1, W_RS1, W_RC2, W_RS2 = range(39, 47)
W_PH1, W_C1, W_S1, W_PH2, W_C2, W_S2 = range(47, 53)
# 1.0: do not locate extrema of v and x for the statistics (a caller that never reads them,
# such as an environment step). Contacts are still found: grazing detection locates the
# extremum of v whenever it could reach V.
W_SKIP_EXTREMA = 53
# Curvature bounds of the closed form, for proving a scan step free of switches without a
# root search: |v_p''| <= C_VDD_P (inf with a resonant tone), |v_h''| <= C_VDD_H |(x_h, v_h)|
# at the step start, and |g''| <= C_GDD; likewise for the third derivatives.
C_VDD_P, C_VDD_H, C_GDD = 54, 55, 56
C_VDDD_P, C_VDDD_H, C_GDDD = 57, 58, 59
# Cached with the regular scan step: its transition constants over half a step (midpoint
# of the (v - V)^2 quadrature).
W_M11, W_M12, W_M21, W_M22, W_MC1, W_MS1, W_MC2, W_MS2 = range(60, 68)
# 1.0: do not integrate (v - V)^2 (ST_VR2_INT stays unchanged), for callers that never
# read it, such as a regime sweep.
W_SKIP_VR2 = 68
# Taylor coefficients of the current slip step (event method): x, v, w = v - V and the
# scratch of the series products, TAYLOR_MAX_ORDER + 1 slots each.
TAYLOR_MAX_ORDER = 20
C_TX = 69
C_TV = C_TX + TAYLOR_MAX_ORDER + 1
C_TW = C_TV + TAYLOR_MAX_ORDER + 1
C_TQ = C_TW + TAYLOR_MAX_ORDER + 1
# Whole-interval closed form (``_whole_interval``): constants over the call's span T, keyed
# on (lam, T) and on each tone's frequency (a retuned tone recomputes only its own).
W_I_KEY_LAM, W_I_KEY_T, W_I_KEY_W1, W_I_KEY_W2 = range(C_TQ + TAYLOR_MAX_ORDER + 1,
                                                       C_TQ + TAYLOR_MAX_ORDER + 5)
W_I_F11 = W_I_KEY_LAM + 4  # homogeneous transition over T (4 slots)
W_I_EH = W_I_F11 + 4  # e^(z_h T), z_h = -lam / 2 + i p (re, im)
W_I_EHH = W_I_EH + 2  # E(2 z_h T) (re, im)
W_I_EHC = W_I_EHH + 2  # E(-lam T) (real)
W_I_P = W_I_EHC + 1  # p = sqrt(1 - lam^2 / 4)
# per tone (W_I_TONE1 + i * N_I_TONE): rotation over T, over T / 2, E(2 i w T),
# E((z_h + i w) T), E((z_h - i w) T), each (re, im)
W_I_TONE1 = W_I_P + 1
N_I_TONE = 10
W_I_E12 = W_I_TONE1 + 2 * N_I_TONE  # E(i (w1 + w2) T), E(i (w1 - w2) T)
W_I_KEY_E1, W_I_KEY_E2 = W_I_E12 + 4, W_I_E12 + 5  # the E values' own keys (slip only)
W_I_AMP1, W_I_AMP2 = W_I_E12 + 6, W_I_E12 + 7  # tones' velocity amplitudes (per call)
# Each tone's context constants (``_setup_context``), keyed on its (u, w) and lam: an agent
# retuning one tone recomputes that tone alone. Per tone (W_T_KEY + i * N_T): the keys u, w,
# then its shares of C_VDD_P, C_VDDD_P, C_GDD, C_GDDD, then 1.0 if the tone is too close to
# resonance for the closed form (see CLOSED_FORM_MAX_GAIN).
W_T_KEY = W_I_E12 + 8
N_T = 7
T_NEAR_RES = 6
N_CX = W_T_KEY + 2 * N_T
N_WORK = N_CX

# What a root search evaluates.
K_SLIP_H = 0  # slip (closed form): h = sd * (v - V)
K_SLIP_V = 1  # slip (closed form): v
K_STICK_F = 2  # stick: f = -lam V - x + g
K_DENSE_H = 3  # slip (Taylor polynomial of the step): h = sd * (v - V)
K_DENSE_V = 4  # slip (Taylor polynomial of the step): v


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _wrap(phi):
    if 0.0 <= phi < TWO_PI:
        return phi
    phi = phi - TWO_PI * math.floor(phi / TWO_PI)
    return phi if phi < TWO_PI else 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def reset_stats(stats):
    """Zero the counters of ``stats`` and set the extrema to +-inf."""
    for i in range(stats.shape[0]):
        stats[i] = 0.0
    stats[ST_V_MAX] = -np.inf
    stats[ST_V_MIN] = np.inf
    stats[ST_X_MAX] = -np.inf
    stats[ST_X_MIN] = np.inf


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _note_v(stats, v):
    if v > stats[ST_V_MAX]:
        stats[ST_V_MAX] = v
    if v < stats[ST_V_MIN]:
        stats[ST_V_MIN] = v


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _note_x(stats, x):
    if x > stats[ST_X_MAX]:
        stats[ST_X_MAX] = x
    if x < stats[ST_X_MIN]:
        stats[ST_X_MIN] = x


@njit(cache=True, error_model="numpy", _nrt=False)
def stick_force(P, x, phi1, phi2):
    """Everything but friction acting on a block riding with the belt: -lam V - x + g."""
    return -P[P_LAM] * P[P_V] - x + P[P_U1] * math.cos(phi1) + P[P_U2] * math.cos(phi2)


@njit(cache=True, error_model="numpy", _nrt=False)
def initial_state(P, x0, v0, S):
    """Fill ``S`` for a start at t = 0 with zero tone phases; mode is chosen from the rules."""
    S[S_T] = 0.0
    S[S_X] = x0
    S[S_V] = v0
    S[S_PHI1] = 0.0
    S[S_PHI2] = 0.0
    S[S_MODE] = initial_mode(P, x0, v0, 0.0, 0.0)


@njit(cache=True, error_model="numpy", _nrt=False)
def initial_mode(P, x, v, phi1, phi2):
    """-1/+1 for slip below/above the belt, 0 for stick (v == V and |f| <= xfs)."""
    vr = v - P[P_V]
    if vr > 0.0:
        return 1.0
    if vr < 0.0:
        return -1.0
    f = stick_force(P, x, phi1, phi2)
    if abs(f) <= P[P_XFS]:
        return 0.0
    return 1.0 if f > 0.0 else -1.0


# ----------------------------------------------------------------------------------------
# Closed form of a Coulomb slip step
# ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _homog(tau, lam, p2):
    """Transition matrix of x'' + lam x' + x = 0 over tau, for every damping.

    With p^2 = 1 - lam^2/4, C = cos(p tau) and S = sin(p tau)/p are entire in p^2, so one
    formula covers under-, critically and over-damped motion; near p^2 tau^2 = 0 a series
    avoids dividing by p, and in the over-damped case the two real exponentials are
    formed directly so nothing overflows.
    """
    z = p2 * tau * tau
    if abs(z) < 1e-2:
        c = 1.0 - z / 2.0 * (1.0 - z / 12.0 * (1.0 - z / 30.0 * (1.0 - z / 56.0 * (
            1.0 - z / 90.0 * (1.0 - z / 132.0)))))
        s = tau * (1.0 - z / 6.0 * (1.0 - z / 20.0 * (1.0 - z / 42.0 * (1.0 - z / 72.0 * (
            1.0 - z / 110.0 * (1.0 - z / 156.0))))))
        e = math.exp(-0.5 * lam * tau)
        ec = e * c
        es = e * s
    elif p2 > 0.0:
        p = math.sqrt(p2)
        e = math.exp(-0.5 * lam * tau)
        c, sn = _sincos(p * tau)
        ec = e * c
        es = e * sn / p
    else:
        q = math.sqrt(-p2)
        slow = math.exp(-tau / (0.5 * lam + q))  # rate lam/2 - q, written without cancelling
        fast = math.exp(-(0.5 * lam + q) * tau)
        ec = 0.5 * (slow + fast)
        es = 0.5 * (slow - fast) / q
    return ec + 0.5 * lam * es, es, -es, ec - 0.5 * lam * es


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _tone_d2(w, lam):
    """1 - w^2, lam w and d2 = |1 - w^2 + i lam w|^2, the tone's response denominator."""
    re = 1.0 - w * w
    im = lam * w
    return re, im, re * re + im * im


@njit(cache=True, error_model="numpy", _nrt=False)
def closed_form_conditioned(P) -> bool:
    """False when a tone of P is too close to resonance for the closed form (see
    CLOSED_FORM_MAX_GAIN): the exact method then runs the event method."""
    for i in range(2):
        d2 = _tone_d2(P[P_W1 + i], P[P_LAM])[2]
        if P[P_U1 + i] != 0.0 and 0.0 < d2 < _D2_MIN:
            return False
    return True


@njit(cache=True, error_model="numpy", _nrt=False)
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
    cx[C_B1] = P[P_B1]
    cx[C_B3] = P[P_B3]
    cx[C_P2] = 1.0 - 0.25 * lam * lam
    for i in range(2):
        u = P[P_U1 + i]
        w = P[P_W1 + i]
        key = W_T_KEY + i * N_T
        if same_lam and cx[key] == u and cx[key + 1] == w:
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
            cx[key + 2] = 2.0 * abs(u)
            cx[key + 3] = 2.5 * abs(u)
        else:
            amp = math.sqrt(kc * kc + ks * ks)
            cx[key + 2] = amp * w * w * abs(w)
            cx[key + 3] = amp * w * w * w * w
            cx[W_I_AMP1 + i] = amp * abs(w)
        cx[key + 4] = abs(u) * w * w
        cx[key + 5] = abs(u) * w * w * abs(w)
        cx[key] = u
        cx[key + 1] = w
    b2 = W_T_KEY + N_T
    cx[C_VDD_P] = cx[W_T_KEY + 2] + cx[b2 + 2]
    cx[C_VDDD_P] = cx[W_T_KEY + 3] + cx[b2 + 3]
    cx[C_GDD] = cx[W_T_KEY + 4] + cx[b2 + 4]
    cx[C_GDDD] = cx[W_T_KEY + 5] + cx[b2 + 5]


@njit(cache=True, error_model="numpy", _nrt=False)
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


@njit(cache=True, error_model="numpy", _nrt=False)
def most_scan_steps(P_rows, spans):
    """The most scan steps any row needs to cover its span, and that row: the floor of a
    run's cost, known before it starts."""
    most = 0.0
    row = 0
    for i in range(P_rows.shape[0]):
        n = spans[i] / _scan_cap(P_rows[i], False)
        if n > most:
            most = n
            row = i
    return most, row


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _particular(cx, tau, c1, s1, c2, s2, sd):
    """Particular solution (x_p, v_p) at relative time tau, tone phases (c_i, s_i) there."""
    xp = -sd * cx[C_XFK]
    vp = 0.0
    if cx[C_U1] != 0.0:
        if cx[C_RES1] != 0.0:
            xp += 0.5 * cx[C_U1] * tau * s1
            vp += 0.5 * cx[C_U1] * (s1 + tau * c1)
        else:
            xp += cx[C_KC1] * c1 + cx[C_KS1] * s1
            vp += cx[C_W1] * (cx[C_KS1] * c1 - cx[C_KC1] * s1)
    if cx[C_U2] != 0.0:
        if cx[C_RES2] != 0.0:
            xp += 0.5 * cx[C_U2] * tau * s2
            vp += 0.5 * cx[C_U2] * (s2 + tau * c2)
        else:
            xp += cx[C_KC2] * c2 + cx[C_KS2] * s2
            vp += cx[C_W2] * (cx[C_KS2] * c2 - cx[C_KC2] * s2)
    return xp, vp


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _slip_start(cx, x, v, c1, s1, c2, s2, sd):
    """Start a closed-form slip step at (x, v) with tone phases (c_i, s_i)."""
    cx[C_XA] = x
    cx[C_VA] = v
    cx[C_C1A] = c1
    cx[C_S1A] = s1
    cx[C_C2A] = c2
    cx[C_S2A] = s2
    cx[C_SD] = sd
    xp, vp = _particular(cx, 0.0, c1, s1, c2, s2, sd)
    cx[C_DX] = x - xp
    cx[C_DV] = v - vp


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _rotate(cx, cr1, sr1, cr2, sr2):
    """Tone phases at the step start advanced by the rotations (cr_i, sr_i)."""
    c1 = cx[C_C1A] * cr1 - cx[C_S1A] * sr1
    s1 = cx[C_S1A] * cr1 + cx[C_C1A] * sr1
    c2 = cx[C_C2A] * cr2 - cx[C_S2A] * sr2
    s2 = cx[C_S2A] * cr2 + cx[C_C2A] * sr2
    return c1, s1, c2, s2


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _rotate_by(cx, tau):
    """Tone phases at the step start advanced by tau (both tones)."""
    cr1, sr1 = _sincos(cx[C_W1] * tau)
    cr2, sr2 = _sincos(cx[C_W2] * tau)
    return _rotate(cx, cr1, sr1, cr2, sr2)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _forcing(cx, c1, s1, c2, s2):
    """g, g' and g'' for tone phases (c_i, s_i)."""
    u1 = cx[C_U1]
    u2 = cx[C_U2]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    g = u1 * c1 + u2 * c2
    gd = -u1 * w1 * s1 - u2 * w2 * s2
    gdd = -u1 * w1 * w1 * c1 - u2 * w2 * w2 * c2
    return g, gd, gdd


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _slip_with(cx, tau, h11, h12, h21, h22, c1, s1, c2, s2):
    """Closed-form slip state at relative time tau: x, v, acceleration and jerk."""
    sd = cx[C_SD]
    xp, vp = _particular(cx, tau, c1, s1, c2, s2, sd)
    x = xp + h11 * cx[C_DX] + h12 * cx[C_DV]
    v = vp + h21 * cx[C_DX] + h22 * cx[C_DV]
    g, gd, _ = _forcing(cx, c1, s1, c2, s2)
    acc = -cx[C_LAM] * v - x - sd * cx[C_XFK] + g
    jerk = -cx[C_LAM] * acc - v + gd
    return x, v, acc, jerk


@njit(cache=True, error_model="numpy", _nrt=False)
def _slip_at(cx, tau):
    x, v, acc, jerk, _, _, _, _ = _slip_and_phases_at(cx, tau)
    return x, v, acc, jerk


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _slip_and_phases_at(cx, tau):
    """``_slip_at`` plus the tones' cos/sin there (a switch needs both)."""
    h11, h12, h21, h22 = _homog(tau, cx[C_LAM], cx[C_P2])
    c1, s1, c2, s2 = _rotate_by(cx, tau)
    x, v, acc, jerk = _slip_with(cx, tau, h11, h12, h21, h22, c1, s1, c2, s2)
    return x, v, acc, jerk, c1, s1, c2, s2


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _slip_mid_and_end(cx, tau):
    """v at tau / 2 and the state and tones' cos/sin at tau, from one evaluation at tau / 2:
    the transition over tau is its square and the rotations are doubled (a few ulps), so
    a step whose (v - V)^2 quadrature needs its midpoint pays for one evaluation, not two."""
    hm = 0.5 * tau
    m11, m12, m21, m22 = _homog(hm, cx[C_LAM], cx[C_P2])
    cm1, sm1 = _sincos(cx[C_W1] * hm)
    cm2, sm2 = _sincos(cx[C_W2] * hm)
    mc1, ms1, mc2, ms2 = _rotate(cx, cm1, sm1, cm2, sm2)
    _, v_mid, _, _ = _slip_with(cx, hm, m11, m12, m21, m22, mc1, ms1, mc2, ms2)
    c1, s1, c2, s2 = _rotate(cx, cm1 * cm1 - sm1 * sm1, 2.0 * sm1 * cm1, cm2 * cm2 - sm2 * sm2,
                             2.0 * sm2 * cm2)
    x, v, acc, jerk = _slip_with(cx, tau, m11 * m11 + m12 * m21, m11 * m12 + m12 * m22,
                                 m21 * m11 + m22 * m21, m21 * m12 + m22 * m22, c1, s1, c2, s2)
    return v_mid, x, v, acc, jerk, c1, s1, c2, s2


@njit(cache=True, error_model="numpy", _nrt=False)
def _stick_at(cx, tau):
    """Stick state at relative time tau: x and f, f', f''."""
    c1, s1, c2, s2 = _rotate_by(cx, tau)
    x = cx[C_XA] + cx[C_V] * tau
    g, gd, gdd = _forcing(cx, c1, s1, c2, s2)
    return x, -cx[C_LAM] * cx[C_V] - x + g, -cx[C_V] + gd, gdd


# ----------------------------------------------------------------------------------------
# Dense output of a Taylor slip step: the series itself, in tau from the step start
# ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", _nrt=False)
def _dense_v(cx, tau):
    """v, v', v'' of the current Taylor step at relative time tau (Horner)."""
    n = int(cx[C_TN])
    p = cx[C_TV + n]
    d1 = 0.0
    d2 = 0.0
    for k in range(n - 1, -1, -1):
        d2 = d2 * tau + d1
        d1 = d1 * tau + p
        p = p * tau + cx[C_TV + k]
    return p, d1, 2.0 * d2


@njit(cache=True, error_model="numpy", _nrt=False)
def _dense_x(cx, tau):
    n = int(cx[C_TN])
    p = cx[C_TX + n]
    for k in range(n - 1, -1, -1):
        p = p * tau + cx[C_TX + k]
    return p


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _dense_bounds(cx, L):
    """Bounds on |v''| and |v'''| over [0, L] of the current Taylor step's polynomial."""
    n = int(cx[C_TN])
    m2 = 0.0
    m3 = 0.0
    for k in range(n, 1, -1):
        ak = abs(cx[C_TV + k]) * (k * (k - 1))
        m2 = m2 * L + ak
        if k >= 3:
            m3 = m3 * L + ak * (k - 2)
    return m2, m3


@njit(cache=True, error_model="numpy", _nrt=False)
def _feval(cx, kind, tau):
    """Value, first and second derivative of the searched function at relative time tau."""
    if kind == K_SLIP_H:
        _, v, acc, jerk = _slip_at(cx, tau)
        sd = cx[C_SD]
        return sd * (v - cx[C_V]), sd * acc, sd * jerk
    if kind == K_SLIP_V:
        _, v, acc, jerk = _slip_at(cx, tau)
        return v, acc, jerk
    if kind == K_STICK_F:
        _, f, fd, fdd = _stick_at(cx, tau)
        return f, fd, fdd
    v, dv, ddv = _dense_v(cx, tau)
    if kind == K_DENSE_H:
        sd = cx[C_SD]
        return sd * (v - cx[C_V]), sd * dv, sd * ddv
    return v, dv, ddv


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _hermite_root(flo, fhi, dlo, dhi, qlo, qhi, H):
    """Fraction of a bracket of length H where the quintic Hermite interpolant of F (value,
    slope dlo/dhi and curvature qlo/qhi at both ends) vanishes: two Halley steps on it from
    the secant point, no evaluation of F. The interpolant is within H^6 |F^(6)| / 46080 of
    F, so on a scan step of a radian this typically lies within ~1e-5 H of the root (median
    3e-6 H on random sinusoids), close enough that one Halley step of F itself lands on it
    to rounding. Only a start: where F barely dips through 0 the two steps can land far
    off or outside (0, 1) (the caller then starts at the secant point), and the bracketed
    search stays exact either way. NaN data give NaN."""
    df = fhi - flo
    d0 = dlo * H
    d1 = dhi * H
    q0 = qlo * H * H
    q1 = qhi * H * H
    a2 = 0.5 * q0
    a3 = 10.0 * df - 6.0 * d0 - 4.0 * d1 - 1.5 * q0 + 0.5 * q1
    a4 = -15.0 * df + 8.0 * d0 + 7.0 * d1 + 1.5 * q0 - q1
    a5 = 6.0 * df - 3.0 * (d0 + d1) - 0.5 * (q0 - q1)
    s = flo / (flo - fhi)
    for _ in range(2):
        p = flo + s * (d0 + s * (a2 + s * (a3 + s * (a4 + s * a5))))
        dp = d0 + s * (2.0 * a2 + s * (3.0 * a3 + s * (4.0 * a4 + s * (5.0 * a5))))
        ddp = 2.0 * a2 + s * (6.0 * a3 + s * (12.0 * a4 + s * (20.0 * a5)))
        s = s - 2.0 * p * dp / (2.0 * dp * dp - p * ddp)
    return s


@njit(cache=True, error_model="numpy", _nrt=False)
def _bracket(cx, kind, deriv, offset, lo, hi, flo, fhi, dlo, dhi, qlo, qhi, rel_tol):
    """Shrink a bracket [lo, hi] of a root of F to rounding level; return (lo, hi).

    F is ``value - offset`` (deriv = 0) or the first derivative (deriv = 1) of ``kind``;
    ``flo`` and ``fhi`` have opposite signs or ``fhi`` is 0; F' and F'' at the ends
    (``dlo``, ``dhi``, ``qlo``, ``qhi``, NaN if unknown) place the first point. Halley
    steps (Newton steps for a derivative's root) from the last point, kept inside the
    bracket, fall back to bisection; once a step is below half the
    tolerance the next point is placed just past the root so the bracket closes from both
    sides. The returned ``hi`` is on ``fhi``'s side of the root.
    """
    if fhi == 0.0:
        return hi, hi
    if flo == 0.0:
        return lo, lo
    tol = rel_tol * (abs(lo) + abs(hi)) + 1e-300
    # start at the root of the ends' Hermite interpolant, else at the secant point (kept
    # off the ends): a step is short against the curvature, so either is already close
    # and Halley needs few iterations (measured, self_excited: 2.5 evaluations a contact
    # search and 2.4 a stick exit's, instead of 4.2 and 4.1 from the secant point)
    frac = _hermite_root(flo, fhi, dlo, dhi, qlo, qhi, hi - lo)
    if not 0.0 < frac < 1.0:
        frac = min(0.95, max(0.05, flo / (flo - fhi)))
    t = lo + (hi - lo) * frac
    pos_lo = flo > 0.0
    for _ in range(MAX_ROOT_ITER):
        f0, f1, f2 = _feval(cx, kind, t)
        if deriv == 0:
            f = f0 - offset
            df = f1
        else:
            f = f1
            df = f2
        if f == 0.0:
            return t, t
        if (f > 0.0) == pos_lo:
            lo = t
        else:
            hi = t
        if hi - lo <= tol:
            break
        tn = -1.0
        if df != 0.0:
            # Halley's step where the second derivative is known (value searches), Newton's
            # otherwise
            den = df if deriv != 0 else df - 0.5 * f * f2 / df
            tn = t - f / den
            # converged from one side: probe just across the root, half a tolerance past
            # it, so the bracket with t closes at once (a whole one often left it wider
            # than the tolerance, costing another evaluation)
            if abs(tn - t) < 0.5 * tol:
                tn = tn + (0.5 * tol if tn > t else -0.5 * tol)
        if not (lo < tn < hi):
            tn = 0.5 * (lo + hi)
        t = tn
    return lo, hi


@njit(cache=True, error_model="numpy", _nrt=False)
def _root(cx, kind, offset, lo, hi, flo, fhi, dlo, dhi, qlo, qhi):
    """Point of a bracket of a root of ``kind`` - offset on ``fhi``'s side (where the
    switch has happened); its derivatives at the ends as in ``_bracket``."""
    _, b = _bracket(cx, kind, 0, offset, lo, hi, flo, fhi, dlo, dhi, qlo, qhi, EVENT_REL_TOL)
    return b


@njit(cache=True, error_model="numpy", _nrt=False)
def _extremum(cx, kind, lo, hi, dlo, dhi, ddlo, ddhi, dddlo, dddhi):
    """Relative time of the extremum of ``kind`` in [lo, hi], from its derivative's signs
    (``dlo``, ``dhi``), and its second and third derivatives there (NaN if unknown)."""
    a, b = _bracket(cx, kind, 1, 0.0, lo, hi, dlo, dhi, ddlo, ddhi, dddlo, dddhi,
                    EXTREMUM_REL_TOL)
    return 0.5 * (a + b)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _start_slope(cx, fresh, h0, d0, x, v):
    """h' at a slip step's start, for the contact search.

    A phase that starts on the switching surface (``fresh``, h0 <= 0) leaves stick or
    reverses with h' = |f| - x_fk >= x_fs - x_fk >= 0, so a negative h' there within the
    rounding of the acceleration's terms is taken as 0. A larger negative one (a given
    state, or an excitation retuned between calls) heads to the other side at once and is
    kept: the contact is then at the start (it was clamped to 0 too, and a dip of h below
    0 that came back within the step went unseen: slip on with v past V, status OK).
    """
    if fresh and h0 <= 0.0 and d0 < 0.0:
        noise = GRAZE_REL * (
            abs(cx[C_LAM] * v) + abs(x) + cx[C_XFK] + abs(cx[C_U1]) + abs(cx[C_U2]))
        if d0 >= -noise:
            return 0.0
    return d0


#: ``_unresolved_return``'s answer where h is resolved (the contact search goes on)
_RESOLVED = -2.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _unresolved_return(L, h0, d0, q0, h1, tol):
    """Contact time of a slip step that starts on the switching surface heading off it while
    h = sd (v - V) never reads above rounding (``tol``): -1 (no contact in the step) or
    the time h returns to 0; ``_RESOLVED`` where that does not apply.

    Leaving stick with x_fs = x_fk (h' = 0, h'' > 0), or reversing just past the static
    level (h' tiny, h'' < 0), h stays within a few ulps of 0 for a while: its computed
    values are rounding noise. Reading a contact at the start from them ended each new
    phase where it began, without time moving, until the event cap stopped the run as
    "chattering"; a root search on them placed the return up to 30 % of the excursion
    off. The derivatives are resolved: near the start h = d0 t + q0 t^2 / 2 + O(t^3), so
    h rises and comes back (q0 < 0) at -2 d0 / q0, where the contact is taken (the state
    there differs from the excursion's by rounding only).
    """
    if not (abs(h0) <= tol and (d0 > 0.0 or (d0 == 0.0 and q0 > 0.0))):
        return _RESOLVED
    if q0 < 0.0:
        back = -2.0 * d0 / q0
        if back < L:
            return back
        return -1.0 if h1 >= -tol else L
    return -1.0 if h1 >= -tol else _RESOLVED


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _contact_time(cx, kind, L, h0, d0, q0, h1, d1, q1, t_ext, h_ext, q_ext):
    """First relative time in (0, L] where h = sd (v - V) reaches 0, or -1 (0: at once).

    ``t_ext``/``h_ext`` describe the interior extremum of h (t_ext < 0: none); q0, q1 and
    q_ext are h'' at 0, L and t_ext (they place the root search's first point). A phase
    that starts on the switching surface (h0 = 0, d0 clamped to >= 0 by the caller) only
    ends once h has been positive, or where ``_unresolved_return`` says when it never
    rises above rounding.
    """
    tol = GRAZE_REL * max(1.0, abs(cx[C_V]))
    if t_ext >= 0.0 and d0 > 0.0:  # h rises to a maximum, then falls
        if h1 <= 0.0:
            if h_ext <= tol:
                te = _unresolved_return(L, h0, d0, q0, h1, tol)
                if te != _RESOLVED:
                    return te
                if h_ext <= 0.0:
                    return 0.0
            return _root(cx, kind, 0.0, t_ext, L, h_ext, h1, 0.0, d1, q_ext, q1)
        return -1.0
    if t_ext >= 0.0 and d0 < 0.0:  # h falls to a minimum (grazing if it only touches 0)
        if h_ext <= 0.0:
            if h0 <= 0.0:
                return 0.0
            return _root(cx, kind, 0.0, 0.0, t_ext, h0, h_ext, d0, 0.0, q0, q_ext)
        # a minimum within rounding of 0 is a touch: which side of 0 the computed value
        # lands on is an accident of the last bit
        if h_ext <= tol:
            return t_ext
        return -1.0
    if h1 <= 0.0:
        if h0 <= 0.0:
            te = _unresolved_return(L, h0, d0, q0, h1, tol)
            return 0.0 if te == _RESOLVED else te
        return _root(cx, kind, 0.0, 0.0, L, h0, h1, d0, d1, q0, q1)
    return -1.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _x_extrema_between(cx, kind, stats, a, b, va, vb, vabs):
    """Displacement extremum where v changes sign on a monotone piece [a, b] of v.

    ``vabs`` bounds |v| over the whole step, so |x - x(0)| <= vabs * b: when that cannot
    reach past the recorded extrema the search is skipped (it matters once the motion
    has decayed to rounding noise, where v flips sign every step).
    """
    if va * vb < 0.0:
        x0 = cx[C_XA]
        reach = vabs * b * 1.0000001
        if x0 + reach <= stats[ST_X_MAX] and x0 - reach >= stats[ST_X_MIN]:
            return
        t = _bracket(cx, kind, 0, 0.0, a, b, va, vb, math.nan, math.nan, math.nan, math.nan,
                     EXTREMUM_REL_TOL)[1]
        if kind == K_SLIP_V:
            x, _, _, _ = _slip_at(cx, t)
        else:
            x = _dense_x(cx, t)
        _note_x(stats, x)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _stays_positive(k0, d0, k1, d1, L, M):
    """Proof that k > 0 on [0, L] from k, k' at both ends and a bound M on |k''|.

    k lies above both k0 + d0 t - M t^2 / 2 and k1 - d1 (L - t) - M (L - t)^2 / 2. The
    larger of these concave bounds is smallest at an end or where they cross (their
    difference is linear in t), so one evaluation decides. False means "not proven".
    """
    if not (k0 > 0.0 and k1 > 0.0 and M < math.inf):
        return False
    slope = d0 - d1 - M * L
    if slope == 0.0:
        return True
    t = -(k0 - k1 + d1 * L + 0.5 * M * L * L) / slope
    if not (0.0 < t < L):
        return True
    return k0 + t * (d0 - 0.5 * M * t) > 0.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _extremum_matters(cx, stats, sd, v0, v1, a0, a1, L, V, vdd_max):
    """Can the interior extremum of v on this step change v's extrema or touch v = V?

    acc goes from a0 to a1 through 0, so |v - v(end)| <= max(|a0|, |a1|) L on a step whose
    acceleration is monotone; a factor 2 covers the mild non-monotonicity a short step
    allows. A touch is ruled out for certain when ``vdd_max`` (a bound on |v''| over the
    step, inf if unknown) proves sd (v - V) > 0 throughout.
    """
    reach = 2.0 * max(abs(a0), abs(a1)) * L
    top = max(v0, v1) + reach
    bottom = min(v0, v1) - reach
    if cx[W_SKIP_EXTREMA] != 1.0 and (top > stats[ST_V_MAX] or bottom < stats[ST_V_MIN]):
        return True
    if not bottom <= V <= top:
        return False
    return not _stays_positive(sd * (v0 - V), sd * a0, sd * (v1 - V), sd * a1, L, vdd_max)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _slip_extrema(cx, kind, stats, tau_e, t_ext, v_ext, v0, v1, x1):
    """Extrema of v and x over a slip step [0, tau_e] (t_ext: v's interior extremum)."""
    _note_v(stats, v1)
    _note_x(stats, x1)
    if cx[W_SKIP_EXTREMA] == 1.0:
        pass
    elif 0.0 <= t_ext <= tau_e:
        _note_v(stats, v_ext)
        vabs = max(abs(v0), abs(v_ext), abs(v1))
        _x_extrema_between(cx, kind, stats, 0.0, t_ext, v0, v_ext, vabs)
        _x_extrema_between(cx, kind, stats, t_ext, tau_e, v_ext, v1, vabs)
    else:
        _x_extrema_between(cx, kind, stats, 0.0, tau_e, v0, v1, max(abs(v0), abs(v1)))


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _slip_stats(cx, kind, stats, tau_e, t_ext, v_ext, v0, a0, j0, v1, a1, j1, x1, v_mid, V):
    """Extrema and the (v - V)^2 integral over a slip step [0, tau_e].

    v, v', v'' at both ends, and v at the midpoint unless ``v_mid`` is NaN.
    """
    _slip_extrema(cx, kind, stats, tau_e, t_ext, v_ext, v0, v1, x1)
    if cx[W_SKIP_VR2] == 1.0:
        return
    # Hermite quadrature of y = (v - V)^2 from y, y', y'' at both ends and, if given, y at
    # the midpoint: exact for degree 7 (5 without the midpoint). y' = 2 (v - V) a and
    # y'' = 2 (a^2 + (v - V) j), with a = v', j = v''.
    r0 = v0 - V
    r1 = v1 - V
    dy0 = 2.0 * r0 * a0
    dy1 = 2.0 * r1 * a1
    ddy0 = 2.0 * (a0 * a0 + r0 * j0)
    ddy1 = 2.0 * (a1 * a1 + r1 * j1)
    if math.isnan(v_mid):
        stats[ST_VR2_INT] += tau_e * (0.5 * (r0 * r0 + r1 * r1) + tau_e * (
            0.1 * (dy0 - dy1) + tau_e * (ddy0 + ddy1) / 120.0))
    else:
        rm = v_mid - V
        stats[ST_VR2_INT] += tau_e * ((19.0 / 70.0) * (r0 * r0 + r1 * r1) + (16.0 / 35.0) * rm * rm
                                      + tau_e * ((1.0 / 35.0) * (dy0 - dy1)
                                                 + tau_e * (ddy0 + ddy1) / 840.0))


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _vr2_from_values(h, r0, r1, mean):
    """Integral of r^2 over a step of length h from r = v - V at both ends and its mean
    (from the displacement): exact for r quadratic in time.

    For Rosenbrock steps, where v' and v'' from the equation of motion are useless: in a
    stiff stretch they carry the state's rounding times |df/dv| and its square, which in
    ``_slip_stats``' Hermite rule made the integral wrong by up to several times itself.
    The mean's own error telescopes: it is the displacement's error at the step's ends.
    """
    d = mean - 0.5 * (r0 + r1)  # r = r0 (1 - s) + r1 s + 6 d s (1 - s), s in [0, 1]
    return h * ((r0 * r0 + r0 * r1 + r1 * r1) / 3.0 + d * (r0 + r1) + 1.2 * d * d)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _jerk(cx, v, a, s1, s2):
    """v'' in slip from v, v' and the tones' sines (the friction law's slope included)."""
    vr = v - cx[C_V]
    slope = cx[C_B1] - 3.0 * cx[C_B3] * vr * vr
    return (slope - cx[C_LAM]) * a - v - (cx[C_U1] * cx[C_W1] * s1 + cx[C_U2] * cx[C_W2] * s2)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _sign_kept(k0, k1, L, M):
    """Proof that k keeps one strict sign on [0, L] from its end values and |k'| <= M."""
    if k0 > 0.0 and k1 > 0.0:
        return k0 + k1 > M * L
    if k0 < 0.0 and k1 < 0.0:
        return -(k0 + k1) > M * L
    return False


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _one_extremum_at_most(h0, d0, h1, d1, hdd0, hdd1, L, M2, M3, cap):
    """May a slip step [0, L] go to the contact search, which handles one extremum of h?

    Yes if h = sd (v - V) provably stays positive (no contact at all), or h' provably
    keeps its sign (h monotone: no extremum), or h'' does (h' monotone: one extremum at
    most), or the step is already tiny. Otherwise the caller halves the step, so no dip
    of h to 0 can hide between two extrema, however long the scan step.
    """
    return (_stays_positive(h0, d0, h1, d1, L, M2) or _monotone(d0, hdd0, d1, hdd1, L, M3)
            or _sign_kept(hdd0, hdd1, L, M3) or L <= MIN_SPLIT * cap)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _monotone(d0, dd0, d1, dd1, L, M):
    """Proof that a function keeps a monotone course on [0, L]: its derivative (d0, d1 at
    the ends, with derivatives dd0, dd1 and |third derivative| <= M) keeps one sign. The
    usual case at a contact, where a step that ends past the switch would otherwise be
    halved."""
    return _stays_positive(d0, dd0, d1, dd1, L, M) or _stays_positive(-d0, -dd0, -d1, -dd1,
                                                                     L, M)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _stick_held(cx, L, f0, fd0, f1, fd1):
    """Proof that |f| <= xfs holds on a whole stick step [0, L] (f'' = g'' in stick)."""
    xfs = cx[C_XFS]
    M = cx[C_GDD]
    return _stays_positive(xfs - f0, -fd0, xfs - f1, -fd1, L, M) and _stays_positive(
        xfs + f0, fd0, xfs + f1, fd1, L, M)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _stick_exit_time(cx, L, f0, fd0, fdd0, f1, fd1, fdd1):
    """First relative time in [0, L] where |f| exceeds xfs during a stick, or -1.

    Each side (f > xfs, f < -xfs) is checked on the monotone pieces of f, split at the
    interior extremum of f when f' changes sign, so a peak of |f| inside the step that
    pokes past xfs is not missed. The caller makes sure f has one extremum at most.
    """
    xfs = cx[C_XFS]
    t_ext = -1.0
    f_ext = 0.0
    fdd_ext = 0.0
    if fd0 * fd1 < 0.0:
        t_ext = _extremum(cx, K_STICK_F, 0.0, L, fd0, fd1, fdd0, fdd1, math.nan, math.nan)
        _, f_ext, _, fdd_ext = _stick_at(cx, t_ext)
    best = -1.0
    tie = _force_tie(cx, cx[C_XA])
    for side in (1.0, -1.0):
        off = side * xfs  # the root searched is f = off; violated where side * f > xfs
        # past xfs at the start: leave now, unless by rounding only with |f| falling
        # (see _force_tie), which holds as f = off
        held_tie = side * f0 > xfs and side * f0 - xfs <= tie and side * fd0 <= 0.0
        if side * f0 > xfs and not held_tie:
            return 0.0
        te = -1.0
        if t_ext >= 0.0:
            if side * fd0 > 0.0:  # f heads to this side first and turns inside the step
                if side * f_ext > xfs:
                    te = _root(cx, K_STICK_F, off, 0.0, t_ext, f0 - off, f_ext - off, fd0,
                               0.0, fdd0, fdd_ext)
            elif side * f1 > xfs:  # f turns back towards this side and crosses after
                if side * f_ext > xfs:  # (a held tie that turns before it clears xfs)
                    te = t_ext
                else:
                    te = _root(cx, K_STICK_F, off, t_ext, L, f_ext - off, f1 - off, 0.0,
                               fd1, fdd_ext, fdd1)
        elif side * f1 > xfs and not held_tie:
            te = _root(cx, K_STICK_F, off, 0.0, L, f0 - off, f1 - off, fd0, fd1, fdd0, fdd1)
        if te >= 0.0 and (best < 0.0 or te < best):
            best = te
    return best


# ----------------------------------------------------------------------------------------
# Shared per-step pieces
# ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _record_event(ev_t, ev_kind, ev_x, counts, t, kind, x):
    n = counts[0]
    if n >= ev_t.shape[0]:
        return False
    ev_t[n] = t
    ev_kind[n] = kind
    ev_x[n] = x
    counts[0] = n + 1
    return True


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _log_event(ev_t, ev_kind, ev_x, counts, t, kind, x, n_events, max_events):
    """Record switch number ``n_events`` when a buffer is given; the run's status after it."""
    status = STATUS_OK
    if ev_t is not None:
        if not _record_event(ev_t, ev_kind, ev_x, counts, t, kind, x):
            status = STATUS_BUFFER_FULL
    if n_events > max_events:
        status = STATUS_EVENT_CAP
    return status


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _force_tie(cx, x):
    """How far |f| may pass x_fs and still be taken as x_fs: the rounding of f's terms.

    At a regime boundary a contact lands with |f| = x_fs to the last bits, where the
    computed f falls on either side by accident. Taken as a pass, a falling |f| made a
    reversal whose slip (h' = |f| - x_fk ~ 0 when x_fs = x_fk) came back at once to the
    same tie, or a stick left again at once: hundreds of switches ~1e-16 apart, or the
    event cap. A tie with |f| falling sticks, and a stick holds through it.
    """
    return GRAZE_REL * (
        abs(cx[C_LAM] * cx[C_V]) + abs(x) + abs(cx[C_U1]) + abs(cx[C_U2]))


@njit(cache=True, error_model="numpy", _nrt=False)
def _contact_outcome(cx, stats, x, c1, s1, c2, s2, sd):
    """Mode after slip in direction sd reaches v = V at x (tone phases c_i = cos, s_i =
    sin): stick, or reverse."""
    f = -cx[C_LAM] * cx[C_V] - x + cx[C_U1] * c1 + cx[C_U2] * c2
    excess = abs(f) - cx[C_XFS]
    if excess > 0.0 and excess <= _force_tie(cx, x):
        fd = -cx[C_V] - cx[C_U1] * cx[C_W1] * s1 - cx[C_U2] * cx[C_W2] * s2
        if f * fd <= 0.0:  # |f| not rising
            excess = 0.0
    if excess <= 0.0:
        stats[ST_N_STICK] += 1.0
        return 0.0, EVENT_STICK
    stats[ST_N_REVERSAL] += 1.0
    return (1.0 if f > 0.0 else -1.0), EVENT_REVERSAL


@njit(cache=True, error_model="numpy", _nrt=False)
def _stick_outcome(cx, stats, x, c1, c2):
    f = -cx[C_LAM] * cx[C_V] - x + cx[C_U1] * c1 + cx[C_U2] * c2
    stats[ST_N_SLIP] += 1.0
    return 1.0 if f > 0.0 else -1.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _renorm(c, s):
    k = 1.5 - 0.5 * (c * c + s * s)
    return c * k, s * k



# ----------------------------------------------------------------------------------------
# A whole call in one closed-form step (stats-only callers that read no extrema)
# ----------------------------------------------------------------------------------------
# In slip, v is a damped oscillation plus two sinusoids, so over a call [0, T]:
# * sd (v - V) is bounded below by the sum of each part's own lowest value: a tone's over
#   the arc its phase sweeps (minus its amplitude if the arc passes its trough, else its
#   lower end value), the damped part's from its ends and a bound on its curvature. When
#   that sum stays above 0 there is no contact in the whole call, and one closed-form
#   step covers it however many scan steps the tones' speed would otherwise take.
# * the (v - V)^2 integral is exact: with each part written Re(a_k e^(z_k t)), a product of
#   two parts integrates to T E((z_k + z_l) T) terms, E(s) = (e^s - 1) / s, whose values
#   depend only on (lam, w1, w2, T) and are cached.
# In stick, f = -lam V - x0 - V t + g(t) is bounded against +-xfs the same way.
# Whatever is not proven goes to the scan. The damped part must oscillate (p^2 >= I_P2_MIN,
# so 1 / p stays tame) and no tone may be resonant.
I_P2_MIN = 0.01
I_MARGIN = 1e-12  # clearance the proofs demand, relative to the size of the terms


@njit(cache=True, error_model="numpy", _nrt=False)
def _sincos_long(t):
    """cos and sin of |t| <= 8 by halving into ``_sincos``'s series and doubling back
    (a few ulps); libm beyond."""
    if not abs(t) <= 8.0:
        return math.cos(t), math.sin(t)
    k = 0
    while abs(t) > 1.0:
        t *= 0.5
        k += 1
    c, s = _sincos(t)
    for _ in range(k):
        c, s = c * c - s * s, 2.0 * s * c
    return c, s


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _e1(s, es):
    """E(s) = (e^s - 1) / s from s and es = e^s (complex), in real arithmetic.

    Directly while |s| >= 0.01 (the rounding of e^s then costs at most ~100 ulps of E);
    below, the series sum s^k / (k + 1)!, whose 7 terms leave < 1e-16.
    """
    a = s.real
    b = s.imag
    r2 = a * a + b * b
    if r2 < 1e-4:
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


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _cget(cx, k):
    return complex(cx[k], cx[k + 1])


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _cset(cx, k, z):
    cx[k] = z.real
    cx[k + 1] = z.imag


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
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


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
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
    r2 = _cget(cx, W_I_TONE1 + N_I_TONE)
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


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
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


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _lowest(amp, y0, y1, c0, s0, cm, sm, c1, s1, alpha):
    """Lowest value over the call of a sinusoid amp cos(psi) whose direction amp (cos psi,
    sin psi) sweeps the arc alpha from (c0, s0) through (cm, sm) to (c1, s1), with end
    values y0, y1: -amp if the arc passes the trough psi = pi, else the lower end (cos has
    no other minimum)."""
    if _arc_passes_zero(-c0, -s0, -cm, -sm, -c1, -s1, alpha, I_MARGIN * amp):
        return -amp
    return min(y0, y1)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _tone_dir(w, kc, ks, c, s):
    """Direction of a tone's particular velocity w (ks cos phi - kc sin phi): its value and
    the quadrature component."""
    return w * (ks * c - kc * s), w * (ks * s + kc * c)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _end_call(S, cx, t, x, v, mode, ph1, c1, s1, ph2, c2, s2):
    """Write the state reached back to S, and the tones' cos/sin to the workspace's cache
    (keyed on the phase angles, so the next call starting there skips four libm calls)."""
    S[S_T] = t
    S[S_X] = x
    S[S_V] = v
    S[S_MODE] = mode
    S[S_PHI1] = ph1
    S[S_PHI2] = ph2
    cx[W_PH1], cx[W_C1], cx[W_S1] = ph1, c1, s1
    cx[W_PH2], cx[W_C2], cx[W_S2] = ph2, c2, s2


@njit(cache=True, error_model="numpy", _nrt=False)
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
    t2 = W_I_TONE1 + N_I_TONE
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
    _end_call(S, cx, S[S_T] + T, x1, v1, sd, _wrap(S[S_PHI1] + w1 * T), nc1, ns1,
              _wrap(S[S_PHI2] + w2 * T), nc2, ns2)
    return True


# ----------------------------------------------------------------------------------------
# Exact (closed-form) runner
# ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
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
    if cx[W_T_KEY + T_NEAR_RES] != 0.0 or cx[W_T_KEY + N_T + T_NEAR_RES] != 0.0:
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


@njit(cache=True, error_model="numpy", _nrt=False)
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
    m_reg = max(1, int(math.ceil(dt_reg / cap - 1e-9)))
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
        regular_interval = abs(length - dt_reg) <= 1e-12 * dt_reg
        if regular_interval:
            m = m_reg
        else:
            m = max(1, int(math.ceil(length / cap - 1e-9)))
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


# ----------------------------------------------------------------------------------------
# Event-driven runner: Taylor steps in slip, exact stick
# ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", _nrt=False)
def _rhs_acc(cx, sd, x, v, ph1, ph2):
    """Slip acceleration for any friction law; tone phases given as angles."""
    return _acc(cx[C_LAM], cx[C_V], sd * cx[C_XFK], cx[C_B1], cx[C_B3], cx[C_U1], cx[C_U2],
                x, v, ph1, ph2)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _acc(lam, V, sxfk, b1, b3, u1, u2, x, v, ph1, ph2):
    """Slip acceleration from scalars; terms a configuration zeroes are skipped."""
    a = -lam * v - x - sxfk
    if u1 != 0.0:
        a += u1 * math.cos(ph1)
    if u2 != 0.0:
        a += u2 * math.cos(ph2)
    if b1 != 0.0 or b3 != 0.0:
        vr = v - V
        a += (b1 - b3 * vr * vr) * vr
    return a


# Taylor coefficients (-1)^k / (2k)! and (-1)^k / (2k+1)!, as products (no divisions).
_C2, _C4, _C6, _C8 = -1.0 / 2.0, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0
_C10, _C12, _C14 = -1.0 / 3628800.0, 1.0 / 479001600.0, -1.0 / 87178291200.0
_C16, _C18 = 1.0 / 20922789888000.0, -1.0 / 6402373705728000.0
_S3, _S5, _S7, _S9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
_S11, _S13, _S15 = -1.0 / 39916800.0, 1.0 / 6227020800.0, -1.0 / 1307674368000.0
_S17, _S19 = 1.0 / 355687428096000.0, -1.0 / 121645100408832000.0


@njit(cache=True, error_model="numpy", _nrt=False)
def _sincos(t):
    """cos and sin of t: a Taylor series for |t| <= 1 (error < 1e-18), libm beyond.

    Scan steps keep phase advances within a radian, so the closed form's rotations and
    root searches make no libm calls, which otherwise dominate an environment step.
    """
    if abs(t) > 1.0:
        return math.cos(t), math.sin(t)
    # Estrin's scheme (pairs of terms joined by z^2, z^4, z^8) for all but the leading
    # term, added last: the same polynomials as Horner's rule with half its chain of
    # dependent operations, which root searches wait on.
    z = t * t
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    pc = ((_C2 + _C4 * z) + (_C6 + _C8 * z) * z2) + ((_C10 + _C12 * z) + (_C14 + _C16 * z)
                                                     * z2) * z4 + _C18 * z8
    ps = ((_S3 + _S5 * z) + (_S7 + _S9 * z) * z2) + ((_S11 + _S13 * z) + (_S15 + _S17 * z)
                                                     * z2) * z4 + _S19 * z8
    c = 1.0 + z * pc
    s = t + (t * z) * ps
    return c, s


@njit(cache=True, error_model="numpy", _nrt=False)
def _set_phases(cx, ph1, ph2):
    """cos/sin of the tone phases at a slip step's start, from the angles."""
    cx[C_CP1] = math.cos(ph1)
    cx[C_SP1] = math.sin(ph1)
    cx[C_CP2] = math.cos(ph2)
    cx[C_SP2] = math.sin(ph2)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _step_inputs(cx, sd):
    """What a Taylor or Rosenbrock slip step reads from the context, as scalars (kept
    in registers: the stages then never reload the array)."""
    return (cx[C_LAM], cx[C_V], sd * cx[C_XFK], cx[C_B1], cx[C_B3], cx[C_U1], cx[C_U2],
            cx[C_CP1], cx[C_SP1], cx[C_CP2], cx[C_SP2])


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _end_phases(cx, cp1, sp1, cp2, sp2, ce1, se1, ce2, se2):
    """Tone phases (cos/sin) at a step's end from its start and the rotations (ce_i, se_i);
    stored in cx[C_CE1..C_SE2] for the next step. Returns the forcing's cosines there."""
    c_end1 = cp1 * ce1 - sp1 * se1
    c_end2 = cp2 * ce2 - sp2 * se2
    cx[C_CE1] = c_end1
    cx[C_SE1] = sp1 * ce1 + cp1 * se1
    cx[C_CE2] = c_end2
    cx[C_SE2] = sp2 * ce2 + cp2 * se2
    return c_end1, c_end2


# ----------------------------------------------------------------------------------------
# Taylor-series slip steps (event method)
# ----------------------------------------------------------------------------------------
# The slip equation is a polynomial ODE in (x, v) plus two tones, so the Taylor
# coefficients of its solution follow from a recurrence: Cauchy products for (v - V)^2 and
# (v - V)^3, and the tones' derivatives cycle through cos, -sin, -cos, sin. One step costs
# O(n^2) flops at order n, takes steps several times longer than a 5th-order Runge–Kutta
# method at the same tolerance (~10x at rtol 1e-10), and its dense output is the series
# itself, exact to the step's accuracy everywhere inside it (switches, extrema and output
# times are found on it).
# 1 / k, k = 0 .. 2 TAYLOR_MAX_ORDER + 1 (no divisions in the recurrence and quadrature)
_INV = np.array([0.0] + [1.0 / k for k in range(1, 2 * TAYLOR_MAX_ORDER + 2)])


@njit(cache=True, error_model="numpy", _nrt=False)
def taylor_order(rtol):
    """Order of the Taylor steps for a tolerance: about -ln(tol) / 2 + 1 (Jorba & Zou 2005,
    the order that minimises the work per unit time), within [6, TAYLOR_MAX_ORDER]."""
    n = int(math.ceil(1.0 - 0.5 * math.log(max(rtol, 1e-300))))
    return min(TAYLOR_MAX_ORDER, max(6, n))


# The series' sums may be reassociated (split into parallel partial sums): that shortens
# their dependency chains several-fold, and the result is still deterministic for a given
# build, only not the left-to-right rounding.
_SUMS = {"reassoc", "contract"}


@njit(cache=True, error_model="numpy", _nrt=False)
def _taylor_coeffs(cx, sd, x0, v0, rtol, atol):
    """Taylor coefficients of x and v at the step start (tone cos/sin in cx[C_CP1..]), to
    the order in cx[C_TN]; returns the step length at which the last two terms of the
    series fall to the tolerance (Jorba & Zou's rule, which needs no rejected steps)."""
    lam, V, sxfk, b1, b3, u1, u2, cp1, sp1, cp2, sp2 = _step_inputs(cx, sd)
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    n = int(cx[C_TN])
    cubic = b3 != 0.0
    p1 = u1  # u_i w_i^k / k!
    p2 = u2
    xk = x0
    vk = v0
    wk = v0 - V
    cx[C_TX] = x0
    cx[C_TV] = v0
    for k in range(n):
        cx[C_TW + k] = wk
        fric = b1 * wk
        if cubic:
            # (w^2)_k by symmetry, and (w^3)_k; two partial sums each halve the chains
            q0 = 0.0
            q1 = 0.0
            half = (k + 1) // 2
            i = 0
            while i + 1 < half:
                q0 += cx[C_TW + i] * cx[C_TW + k - i]
                q1 += cx[C_TW + i + 1] * cx[C_TW + k - i - 1]
                i += 2
            if i < half:
                q0 += cx[C_TW + i] * cx[C_TW + k - i]
            q = 2.0 * (q0 + q1)
            if k % 2 == 0:
                q += cx[C_TW + k // 2] * cx[C_TW + k // 2]
            cx[C_TQ + k] = q
            c0 = 0.0
            c1 = 0.0
            i = 1
            while i + 1 <= k:
                c0 += cx[C_TQ + k - i] * cx[C_TW + i]
                c1 += cx[C_TQ + k - i - 1] * cx[C_TW + i + 1]
                i += 2
            if i <= k:
                c0 += cx[C_TQ + k - i] * cx[C_TW + i]
            c = (c0 + c1) + q * cx[C_TW]
            fric -= b3 * c
        m = k & 3
        if m == 0:
            g = p1 * cp1 + p2 * cp2
        elif m == 1:
            g = -(p1 * sp1 + p2 * sp2)
        elif m == 2:
            g = -(p1 * cp1 + p2 * cp2)
        else:
            g = p1 * sp1 + p2 * sp2
        a = fric + g - lam * vk - xk
        if k == 0:
            a -= sxfk
        r = _INV[k + 1]
        xk = vk * r
        vk = a * r
        wk = vk
        cx[C_TX + k + 1] = xk
        cx[C_TV + k + 1] = vk
        p1 *= w1 * r
        p2 *= w2 * r
    cx[C_TW + n] = wk
    # (floored at rounding level: a zero target, or one below what doubles resolve, would
    # shrink the step to nothing and the run would never end)
    size = max(abs(x0), abs(v0))
    eps = max(atol + rtol * size, 1e-16 * max(size, 1.0))
    last = max(abs(cx[C_TX + n]), abs(cx[C_TV + n]))
    prev = max(abs(cx[C_TX + n - 1]), abs(cx[C_TV + n - 1]))
    # h = min((eps / prev)^(1 / (n - 1)), (eps / last)^(1 / n)) times a safety factor
    le = math.log(eps)
    lh = math.inf
    if prev > 0.0:
        lh = (le - math.log(prev)) * _INV[n - 1]
    if last > 0.0:
        lh = min(lh, (le - math.log(last)) * _INV[n])
    return math.exp(lh - 0.7 * _INV[n - 1])


@njit(cache=True, error_model="numpy", _nrt=False, fastmath=_SUMS)
def _taylor_vr2(cx, tau):
    """Integral of (v - V)^2 over [0, tau] of the current Taylor step, exactly:
    tau * sum_ij z_i z_j / (i + j + 1) with z_i = w_i tau^i."""
    n = int(cx[C_TN])
    z = cx[C_TQ:C_TQ + n + 1]
    s = 1.0
    for i in range(n + 1):
        z[i] = cx[C_TW + i] * s
        s *= tau
    total = 0.0
    for i in range(n + 1):
        zi = z[i]
        row = 0.5 * zi * _INV[2 * i + 1]
        for j in range(i + 1, n + 1):
            row += z[j] * _INV[i + j + 1]
        total += zi * row
    return 2.0 * tau * total


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _v_one_extremum(a0, j0, a1, j1, L, m3):
    """Proof that v has at most one extremum on [0, L]: v' keeps its sign, or v'' does
    (v' monotone), given v', v'' at both ends and |v'''| <= m3."""
    s = 1.0 if a0 + a1 >= 0.0 else -1.0
    return _stays_positive(s * a0, s * j0, s * a1, s * j1, L, m3) or _sign_kept(j0, j1, L, m3)


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _carry(cx, t, x1, v1, a1, ph1, ph2, h):
    """Move to the end of an accepted slip step of length h: its (t, x, v, v', phases);
    the end's tone cos/sin become the next step's start (renormalised)."""
    cx[C_CP1], cx[C_SP1] = _renorm(cx[C_CE1], cx[C_SE1])
    cx[C_CP2], cx[C_SP2] = _renorm(cx[C_CE2], cx[C_SE2])
    return t + h, x1, v1, a1, _wrap(ph1 + cx[C_W1] * h), _wrap(ph2 + cx[C_W2] * h)


# Shampine's L-stable Rosenbrock pair of order 4(3) (the "stiff" method of Numerical Recipes):
# stages Y_i = y + sum a_ij g_j at t + alpha_i h, (I / (gamma h) - J) g_i = f(Y_i) +
# gamma_i h f_t + sum c_ij g_j / h; 3 function values and 4 linear solves a step.
_RG = 0.5
_RA21, _RA31, _RA32 = 2.0, 48.0 / 25.0, 6.0 / 25.0
_RC21, _RC31, _RC32 = -8.0, 372.0 / 25.0, 12.0 / 5.0
_RC41, _RC42, _RC43 = -112.0 / 125.0, -54.0 / 125.0, -2.0 / 5.0
_RB1, _RB2, _RB3, _RB4 = 19.0 / 9.0, 1.0 / 2.0, 25.0 / 108.0, 125.0 / 108.0
_RE1, _RE2, _RE4 = 17.0 / 54.0, 7.0 / 36.0, 125.0 / 108.0
_RG1, _RG2, _RG3, _RG4 = 1.0 / 2.0, -3.0 / 2.0, 121.0 / 50.0, 29.0 / 250.0
_RALPHA3 = 3.0 / 5.0
# A slip step is stiff when |df/dv| h exceeds this: the Taylor steps' length is then set by
# their stability (the error control holds them near its limit), not by accuracy.
STIFF_HK = 2.5
# Most Taylor steps between Rosenbrock retries in a stiff stretch where they keep failing
ROS_BACKOFF_MAX = 64.0


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _ros_solve(c, j22, r1, r2):
    """(c I - J) z = r for J = [[0, 1], [-1, j22]]."""
    det = 1.0 + c * (c - j22)
    z1 = (r2 + (c - j22) * r1) / det
    return z1, c * z1 - r1


@njit(cache=True, error_model="numpy", _nrt=False)
def _ros4_step(cx, sd, x0, v0, a0, h):
    """One Rosenbrock step of the slip equation from (x0, v0) (phases in cx).

    Returns x, v and v' at the end and the embedded error of x and v. J is exact: the
    friction law's slope enters only dv'/dv. cos/sin of the tone phases at the step end go
    to cx[C_CE1..C_SE2], as after a Taylor step.
    """
    lam, V, sxfk, b1, b3, u1, u2, cp1, sp1, cp2, sp2 = _step_inputs(cx, sd)
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    vr = v0 - V
    j22 = -lam + b1 - 3.0 * b3 * vr * vr
    gt = -(u1 * w1 * sp1 + u2 * w2 * sp2)  # dg/dt at the step start
    c = 1.0 / (_RG * h)
    ce1, se1 = _sincos(w1 * h)
    ce2, se2 = _sincos(w2 * h)
    c_end1, c_end2 = _end_phases(cx, cp1, sp1, cp2, sp2, ce1, se1, ce2, se2)
    c31, s31 = _sincos(w1 * _RALPHA3 * h)
    c32, s32 = _sincos(w2 * _RALPHA3 * h)
    g_end = u1 * c_end1 + u2 * c_end2
    g_3 = u1 * (cp1 * c31 - sp1 * s31) + u2 * (cp2 * c32 - sp2 * s32)
    g1x, g1v = _ros_solve(c, j22, v0, a0 + h * _RG1 * gt)
    x2 = x0 + _RA21 * g1x
    v2 = v0 + _RA21 * g1v
    f2v = _acc(lam, V, sxfk, b1, b3, 0.0, 0.0, x2, v2, 0.0, 0.0) + g_end
    g2x, g2v = _ros_solve(c, j22, v2 + _RC21 * g1x / h,
                          f2v + h * _RG2 * gt + _RC21 * g1v / h)
    x3 = x0 + _RA31 * g1x + _RA32 * g2x
    v3 = v0 + _RA31 * g1v + _RA32 * g2v
    f3v = _acc(lam, V, sxfk, b1, b3, 0.0, 0.0, x3, v3, 0.0, 0.0) + g_3
    g3x, g3v = _ros_solve(c, j22, v3 + (_RC31 * g1x + _RC32 * g2x) / h,
                          f3v + h * _RG3 * gt + (_RC31 * g1v + _RC32 * g2v) / h)
    g4x, g4v = _ros_solve(c, j22, v3 + (_RC41 * g1x + _RC42 * g2x + _RC43 * g3x) / h,
                          f3v + h * _RG4 * gt + (_RC41 * g1v + _RC42 * g2v + _RC43 * g3v) / h)
    x1 = x0 + _RB1 * g1x + _RB2 * g2x + _RB3 * g3x + _RB4 * g4x
    v1 = v0 + _RB1 * g1v + _RB2 * g2v + _RB3 * g3v + _RB4 * g4v
    ex = _RE1 * g1x + _RE2 * g2x + _RE4 * g4x
    ev = _RE1 * g1v + _RE2 * g2v + _RE4 * g4v
    a1 = _acc(lam, V, sxfk, b1, b3, 0.0, 0.0, x1, v1, 0.0, 0.0) + g_end
    return x1, v1, a1, ex, ev


@njit(cache=True, error_model="numpy", _nrt=False)
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
    h = min(cap, 0.05)  # the last Taylor step's natural length (for the stiffness test)
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
        if t_stop - t <= 1e-13 * max(1.0, abs(t_stop)):
            t = t_stop
            break
        if mode != 0.0:
            # ---------------- one slip step ----------------
            if phases_stale or n_carried >= 64:
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
                    h_ros = hr * min(4.0, max(0.2, 0.9 * (err_r + 1e-30) ** -0.125))
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
                h_floor = 1e-13 * max(1.0, abs(t))
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
                    while j_out < n_out and out_t[j_out] - origin <= t + step_end + 1e-13 * max(1.0,
                                                                                     abs(t)):
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
                while j_out < n_out and out_t[j_out] - origin <= t + step_end + 1e-13 * max(1.0,
                                                                                 abs(t)):
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


# ----------------------------------------------------------------------------------------
# The paper's scheme: fixed-step RK4 with sgn
# ----------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", _nrt=False)
def _sgn_acc(P, x, v, ph1, ph2):
    vr = v - P[P_V]
    s = 1.0 if vr > 0.0 else (-1.0 if vr < 0.0 else 0.0)
    return (-P[P_LAM] * v - x - P[P_XFK] * s + P[P_B1] * vr - P[P_B3] * vr * vr * vr
            + P[P_U1] * math.cos(ph1) + P[P_U2] * math.cos(ph2))


@njit(cache=True, error_model="numpy")
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
    t0 = S[S_T]
    t = t0
    x = S[S_X]
    v = S[S_V]
    ph1 = S[S_PHI1]
    ph2 = S[S_PHI2]
    n_out = 0
    if out_t is not None:
        n_out = out_t.shape[0]
        out_x[0] = x
        out_v[0] = v
        out_mode[0] = 1.0 if v > V else (-1.0 if v < V else 0.0)
    j = 1
    _note_v(stats, v)
    _note_x(stats, x)
    n = int(math.ceil(t_span / dt - 1e-9))
    k1v = _sgn_acc(P, x, v, ph1, ph2)
    status = STATUS_OK
    for i in range(n):
        hh = dt if i < n - 1 else t_span - (n - 1) * dt
        k1x = v
        k2x = v + 0.5 * hh * k1v
        k2v = _sgn_acc(P, x + 0.5 * hh * k1x, k2x, ph1 + 0.5 * hh * w1, ph2 + 0.5 * hh * w2)
        k3x = v + 0.5 * hh * k2v
        k3v = _sgn_acc(P, x + 0.5 * hh * k2x, k3x, ph1 + 0.5 * hh * w1, ph2 + 0.5 * hh * w2)
        k4x = v + hh * k3v
        k4v = _sgn_acc(P, x + hh * k3x, k4x, ph1 + hh * w1, ph2 + hh * w2)
        xn = x + hh / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
        vn = v + hh / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        ph1n = _wrap(ph1 + hh * w1)
        ph2n = _wrap(ph2 + hh * w2)
        an = _sgn_acc(P, xn, vn, ph1n, ph2n)
        tn = t0 + (i + 1) * dt if i < n - 1 else t0 + t_span
        if out_t is not None:
            while j < n_out and out_t[j] <= tn + 1e-12 * max(1.0, abs(tn)):
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


# ----------------------------------------------------------------------------------------
# Public stats-only kernel
# ----------------------------------------------------------------------------------------
def new_workspace(n: int | None = None, *, extrema: bool = True, vr2: bool = True
                  ) -> np.ndarray:
    """Workspace for ``advance_ws``: one row per plant, caches marked empty (NaN).

    ``extrema=False`` skips locating the extrema of v and x (ST_V_MAX ... ST_X_MIN then
    only see step ends), and ``vr2=False`` the (v - V)^2 integral (ST_VR2_INT), for
    callers that do not read them.
    """
    shape = N_WORK if n is None else (n, N_WORK)
    work = np.full(shape, np.nan)
    work[..., W_SKIP_EXTREMA] = 0.0 if extrema else 1.0
    work[..., W_SKIP_VR2] = 0.0 if vr2 else 1.0
    return work


@njit(cache=True, error_model="numpy")
def fresh_workspace(extrema=True, vr2=True):
    """``new_workspace`` for one plant, from compiled code."""
    # all NaN: every cache key compares unequal, so nothing stale is ever reused
    work = np.full(N_WORK, np.nan)
    work[W_SKIP_EXTREMA] = 0.0 if extrema else 1.0
    work[W_SKIP_VR2] = 0.0 if vr2 else 1.0
    return work


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance`` with a caller-owned workspace (see ``new_workspace``).

    Reusing one workspace per plant across calls spares the allocation and, for the
    closed-form method, the transition constants and the tone phases' cos/sin, which is
    most of the cost of a short call such as one control interval of an environment.
    """
    if method == METHOD_EXACT:
        status = _run_exact(P, S, t_span, None, stats, max_events, None, None, None, None,
                            None, None, None, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return _run_event(P, S, t_span, None, stats, max_events, rtol, atol, None, None, None,
                      None, None, None, None, work)


@njit(cache=True, error_model="numpy")
def advance(P, S, t_span, stats, method, rtol, atol, max_events):
    """Advance the state ``S`` in place by ``t_span``, accumulating ``stats``; no trajectory.

    ``method`` is METHOD_EXACT (Coulomb law only; the caller checks; a call with a tone
    too close to resonance runs the event method, see CLOSED_FORM_MAX_GAIN) or
    METHOD_EVENT.
    Tone phases are carried in ``S``, so P's amplitudes and frequencies may change between
    calls without a jump in the force. Returns a STATUS_* code; at most ``max_events``
    switches are allowed in the call (STATUS_EVENT_CAP beyond).
    """
    return advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, fresh_workspace())


@njit(cache=True, error_model="numpy")
def record(P, S, out_t, stats, method, rtol, atol, max_events, out_x, out_v, out_mode, ev_t,
           ev_kind, ev_x, counts):
    """Like ``advance`` over [out_t[0], out_t[-1]], recording the state at ``out_t`` and the
    events (time, kind, x); ``counts`` returns (events recorded, outputs written)."""
    t_span = out_t[out_t.shape[0] - 1] - out_t[0]
    work = fresh_workspace()
    if method == METHOD_EXACT:
        status = _run_exact(P, S, t_span, out_t, stats, max_events, out_x, out_v, out_mode,
                            ev_t, ev_kind, ev_x, counts, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return _run_event(P, S, t_span, out_t, stats, max_events, rtol, atol, out_x, out_v,
                      out_mode, ev_t, ev_kind, ev_x, counts, work)
