"""The state vector S and the statistics: initial mode, stick force, extrema, write-back."""

import math
from typing import NamedTuple

import numpy as np

from ..jit import kernel
from ..layout import S_MODE, S_PHI1, S_PHI2, S_T, S_V, S_X, ST_V_MAX, ST_V_MIN, ST_X_MAX, ST_X_MIN
from ..params import P_LAM, P_U1, P_U2, P_V, P_XFS
from .workspace import W_C1, W_C2, W_PH1, W_PH2, W_S1, W_S2


class Tones(NamedTuple):
    """The cos and sin of both tones' phases at one instant."""

    c1: float
    s1: float
    c2: float
    s2: float


class Phases(NamedTuple):
    """Both tones' phase angles (wrapped) and their cos/sin: what a call ends on."""

    ph1: float
    ph2: float
    tones: Tones


@kernel
def reset_stats(stats):
    """Zero the counters of ``stats`` and set the extrema to +-inf."""
    for i in range(stats.shape[0]):
        stats[i] = 0.0
    stats[ST_V_MAX] = -np.inf
    stats[ST_V_MIN] = np.inf
    stats[ST_X_MAX] = -np.inf
    stats[ST_X_MIN] = np.inf

@kernel
def _note_v(stats, v):
    if v > stats[ST_V_MAX]:
        stats[ST_V_MAX] = v
    if v < stats[ST_V_MIN]:
        stats[ST_V_MIN] = v

@kernel
def _note_x(stats, x):
    if x > stats[ST_X_MAX]:
        stats[ST_X_MAX] = x
    if x < stats[ST_X_MIN]:
        stats[ST_X_MIN] = x

@kernel
def stick_force(P, x, phi1, phi2):
    """Everything but friction acting on a block riding with the belt: -lam V - x + g."""
    return -P[P_LAM] * P[P_V] - x + P[P_U1] * math.cos(phi1) + P[P_U2] * math.cos(phi2)

@kernel
def initial_state(P, x0, v0, S):
    """Fill ``S`` for a start at t = 0 with zero tone phases; mode is chosen from the rules."""
    S[S_T] = 0.0
    S[S_X] = x0
    S[S_V] = v0
    S[S_PHI1] = 0.0
    S[S_PHI2] = 0.0
    S[S_MODE] = initial_mode(P, x0, v0, 0.0, 0.0)

@kernel
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

@kernel
def _end_call(S, cx, t, x, v, mode, phases):
    """Write the state reached back to S, and the tones' cos/sin to the workspace's cache
    (keyed on the phase angles, so the next call starting there skips four libm calls)."""
    ph1 = phases.ph1
    ph2 = phases.ph2
    tones = phases.tones
    S[S_T] = t
    S[S_X] = x
    S[S_V] = v
    S[S_MODE] = mode
    S[S_PHI1] = ph1
    S[S_PHI2] = ph2
    cx[W_PH1], cx[W_C1], cx[W_S1] = ph1, tones.c1, tones.s1
    cx[W_PH2], cx[W_C2], cx[W_S2] = ph2, tones.c2, tones.s2
