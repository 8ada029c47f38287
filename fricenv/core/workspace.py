"""The per-plant workspace ``cx`` of the kernels: its slots, and how to allocate one."""

import numpy as np
from numba import njit

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
