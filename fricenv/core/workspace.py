"""The per-plant workspace ``cx`` of the kernels: its slots, and how to allocate one.

The workspace holds a call's context (the plant's constants), the state of the current step
and caches kept across calls when the caller passes the same workspace (``advance_ws``).
Its layout is the ordered list of slots below (``WORKSPACE.slots``); every offset is
computed from it.
"""

from __future__ import annotations

import numpy as np

from ..friction.kernels import LAW_SCRATCH
from ..friction.spec import SERIES_LEN
from ..jit import kernel
from ..slots import Layout
from .constants import BUDGET_CHECK_STEPS, MAX_STEPS_PER_CALL, MAX_STEPS_PER_TAU

WORKSPACE = Layout("workspace")
_take = WORKSPACE.take

# The plant's parameters, as the kernels read them, and p^2 = 1 - lam^2 / 4.
C_LAM, C_V, C_XFK, C_XFS, C_U1, C_U2, C_W1, C_W2, C_P2 = WORKSPACE.group(
    "C_LAM", "C_V", "C_XFK", "C_XFS", "C_U1", "C_U2", "C_W1", "C_W2", "C_P2")
# Each tone's particular-solution coefficients x_p = kc cos(phi) + ks sin(phi), 1.0 if the
# tone is exactly resonant.
C_KC1, C_KS1, C_KC2, C_KS2, C_RES1, C_RES2 = WORKSPACE.group(
    "C_KC1", "C_KS1", "C_KC2", "C_KS2", "C_RES1", "C_RES2")
# The friction law: its code and its constants inside the kernels (``lc``, made by its
# module's ``prepare``; see :mod:`fricenv.friction.kernels`).
C_LAW = _take("C_LAW")
C_LC = _take("C_LC", 4)
# The current step's start: state, tones' cos/sin, slip direction and distance from the
# particular solution.
C_XA, C_VA, C_C1A, C_S1A, C_C2A, C_S2A, C_SD, C_DX, C_DV = WORKSPACE.group(
    "C_XA", "C_VA", "C_C1A", "C_S1A", "C_C2A", "C_S2A", "C_SD", "C_DX", "C_DV")
C_TN = _take("C_TN")  # order of the current Taylor slip step (its coefficients: C_TX, ...)
# tones' cos/sin at the step start, carried ...
C_CP1, C_SP1, C_CP2, C_SP2 = WORKSPACE.group("C_CP1", "C_SP1", "C_CP2", "C_SP2")
# ... and at the end of the last slip step
C_CE1, C_SE1, C_CE2, C_SE2 = WORKSPACE.group("C_CE1", "C_SE1", "C_CE2", "C_SE2")
# Cache kept across calls when the caller passes the same workspace (``advance_ws``): the
# regular scan step's transition constants, keyed on (lam, w1, w2, h), and each tone's
# cos/sin, keyed on the phase angle last written to S. Keys start as NaN (never equal).
W_KEY_LAM, W_KEY_W1, W_KEY_W2, W_KEY_H = WORKSPACE.group(
    "W_KEY_LAM", "W_KEY_W1", "W_KEY_W2", "W_KEY_H")
W_R11, W_R12, W_R21, W_R22, W_RC1, W_RS1, W_RC2, W_RS2 = WORKSPACE.group(
    "W_R11", "W_R12", "W_R21", "W_R22", "W_RC1", "W_RS1", "W_RC2", "W_RS2")
W_PH1, W_C1, W_S1, W_PH2, W_C2, W_S2 = WORKSPACE.group(
    "W_PH1", "W_C1", "W_S1", "W_PH2", "W_C2", "W_S2")
# 1.0: do not locate extrema of v and x for the statistics (a caller that never reads them,
# such as an environment step). Contacts are still found: grazing detection locates the
# extremum of v whenever it could reach V.
W_SKIP_EXTREMA = _take("W_SKIP_EXTREMA")
# Curvature bounds of the closed form, for proving a scan step free of switches without a
# root search: |v_p''| <= C_VDD_P (inf with a resonant tone), |v_h''| <= C_VDD_H |(x_h, v_h)|
# at the step start, and |g''| <= C_GDD; likewise for the third derivatives.
C_VDD_P, C_VDD_H, C_GDD = WORKSPACE.group("C_VDD_P", "C_VDD_H", "C_GDD")
C_VDDD_P, C_VDDD_H, C_GDDD = WORKSPACE.group("C_VDDD_P", "C_VDDD_H", "C_GDDD")
# Cached with the regular scan step: its transition constants over half a step (midpoint
# of the (v - V)^2 quadrature).
W_M11, W_M12, W_M21, W_M22, W_MC1, W_MS1, W_MC2, W_MS2 = WORKSPACE.group(
    "W_M11", "W_M12", "W_M21", "W_M22", "W_MC1", "W_MS1", "W_MC2", "W_MS2")
# 1.0: do not integrate (v - V)^2 (ST_VR2_INT stays unchanged), for callers that never
# read it, such as a regime sweep.
W_SKIP_VR2 = _take("W_SKIP_VR2")
# Taylor coefficients of the current slip step (event method): x, v, w = v - V and the
# scratch of the series products, TAYLOR_MAX_ORDER + 1 slots each.
TAYLOR_MAX_ORDER = SERIES_LEN - 1
C_TX = _take("C_TX", TAYLOR_MAX_ORDER + 1)
C_TV = _take("C_TV", TAYLOR_MAX_ORDER + 1)
C_TW = _take("C_TW", TAYLOR_MAX_ORDER + 1)
C_TQ = _take("C_TQ", TAYLOR_MAX_ORDER + 1)
# Whole-interval closed form (``_whole_interval``): constants over the call's span T, keyed
# on (lam, T) and on each tone's frequency (a retuned tone recomputes only its own).
W_I_KEY_LAM, W_I_KEY_T, W_I_KEY_W1, W_I_KEY_W2 = WORKSPACE.group(
    "W_I_KEY_LAM", "W_I_KEY_T", "W_I_KEY_W1", "W_I_KEY_W2")
W_I_F11 = _take("W_I_F11", 4)  # homogeneous transition over T
W_I_EH = _take("W_I_EH", 2)  # e^(z_h T), z_h = -lam / 2 + i p (re, im)
W_I_EHH = _take("W_I_EHH", 2)  # E(2 z_h T) (re, im)
W_I_EHC = _take("W_I_EHC")  # E(-lam T) (real)
W_I_P = _take("W_I_P")  # p = sqrt(1 - lam^2 / 4)
# per tone (W_I_TONE1 + i * N_I_TONE): rotation over T, over T / 2, E(2 i w T),
# E((z_h + i w) T), E((z_h - i w) T), each (re, im)
N_I_TONE = 10
W_I_TONE1 = _take("W_I_TONE1", N_I_TONE)
W_I_TONE2 = _take("W_I_TONE2", N_I_TONE)
W_I_E12 = _take("W_I_E12", 4)  # E(i (w1 + w2) T), E(i (w1 - w2) T), each (re, im)
W_I_KEY_E1, W_I_KEY_E2 = WORKSPACE.group("W_I_KEY_E1", "W_I_KEY_E2")  # their keys (slip)
W_I_AMP1, W_I_AMP2 = WORKSPACE.group("W_I_AMP1", "W_I_AMP2")  # tones' velocity amplitudes
# Each tone's context constants (``_setup_context``), keyed on its (u, w) and lam: an agent
# retuning one tone recomputes that tone alone. Per tone (W_T_KEY + i * N_T), the slots of
# TONE_KEYS: the keys u, w, then its shares of C_VDD_P, C_VDDD_P, C_GDD, C_GDDD, then 1.0
# if the tone is too close to resonance for the closed form (see CLOSED_FORM_MAX_GAIN).
TONE_KEYS = Layout("tone keys")
T_U, T_W, T_VDD_P, T_VDDD_P, T_GDD, T_GDDD, T_NEAR_RES = TONE_KEYS.group(
    "T_U", "T_W", "T_VDD_P", "T_VDDD_P", "T_GDD", "T_GDDD", "T_NEAR_RES")
N_T = TONE_KEYS.size
W_T_KEY = _take("W_T_KEY", N_T)
W_T_KEY2 = _take("W_T_KEY2", N_T)
# The call's step budget (see MAX_STEPS_PER_TAU), read at every step, so that another thread
# can end a running call by lowering W_MAX_STEPS_CALL below 0.
W_MAX_STEPS_TAU, W_MAX_STEPS_CALL = WORKSPACE.group("W_MAX_STEPS_TAU", "W_MAX_STEPS_CALL")
# The friction law's own series (its Taylor recurrence), last: only a law that needs them
# touches these slots, and the ones every step reads stay together.
C_TL = _take("C_TL", LAW_SCRATCH)
N_CX = WORKSPACE.size
N_WORK = N_CX


def new_workspace(n: int | None = None, *, extrema: bool = True, vr2: bool = True
                  ) -> np.ndarray:
    """Workspace for ``advance_ws``: one row per plant, caches marked empty (NaN).

    ``extrema=False`` skips locating the extrema of v and x (ST_V_MAX ... ST_X_MIN then
    only see step ends), and ``vr2=False`` the (v - V)^2 integral (ST_VR2_INT), for
    callers that do not read them. The step budget starts at MAX_STEPS_PER_TAU and
    MAX_STEPS_PER_CALL (slots W_MAX_STEPS_TAU, W_MAX_STEPS_CALL).
    """
    shape = N_WORK if n is None else (n, N_WORK)
    work = np.full(shape, np.nan)
    work[..., W_SKIP_EXTREMA] = 0.0 if extrema else 1.0
    work[..., W_SKIP_VR2] = 0.0 if vr2 else 1.0
    work[..., W_MAX_STEPS_TAU] = MAX_STEPS_PER_TAU
    work[..., W_MAX_STEPS_CALL] = MAX_STEPS_PER_CALL
    return work


@kernel(allocates=True)
def fresh_workspace(extrema=True, vr2=True):
    """``new_workspace`` for one plant, from compiled code."""
    # all NaN: every cache key compares unequal, so nothing stale is ever reused
    work = np.full(N_WORK, np.nan)
    work[W_SKIP_EXTREMA] = 0.0 if extrema else 1.0
    work[W_SKIP_VR2] = 0.0 if vr2 else 1.0
    work[W_MAX_STEPS_TAU] = MAX_STEPS_PER_TAU
    work[W_MAX_STEPS_CALL] = MAX_STEPS_PER_CALL
    return work


@kernel
def _budget_check(cx, t, n_call, t_win, n_win0, n_scan):
    """Check a runner's step budget (in ``cx``) before its step number ``n_call`` (from
    1), taken from call time ``t``: (over budget, t_win, n_win0, n_check). The runner
    carries the current unit window's start ``t_win`` and the steps before it ``n_win0``
    (both start at 0) and checks again at step ``n_check``: at most BUDGET_CHECK_STEPS
    steps on and never past a budget's end, so the hot loop pays one compare a step.
    ``n_scan``: the steps a unit of tau may take on top of W_MAX_STEPS_TAU, for the scan
    (SCAN_ALLOWANCE / scan cap: a fast tone's scan is never over budget). A budget lowered
    from another thread ends the call within BUDGET_CHECK_STEPS steps."""
    if t - t_win >= 1.0:
        t_win = t
        n_win0 = n_call - 1.0
    left_win = cx[W_MAX_STEPS_TAU] + n_scan - (n_call - n_win0)
    left_call = cx[W_MAX_STEPS_CALL] - n_call
    over = left_win < 0.0 or left_call < 0.0
    n_check = n_call + max(1.0, min(BUDGET_CHECK_STEPS, left_win, left_call))
    return over, t_win, n_win0, n_check
