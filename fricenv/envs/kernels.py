"""Numba kernels of the RL environments: action scaling, one control interval, reward, obs.

The single environment and the native vector environment call the same inner functions, so
they agree bit for bit. The step kernels allocate nothing of their own (only
``sample_interval_with``, used for rendering, works on copies) and run on the physics
core's stats-only path (an entry kernel such as ``core.advance_exact_ws``, passed in): an
environment step integrates to the next control instant and keeps no trajectory. A plant's
arrays travel between the kernels as one :class:`Plant`.

Kernels that allocate nothing are compiled without numba's reference-counting runtime
(``_nrt=False``, see ``fricenv.jit``): otherwise every per-plant call does atomic count
updates on the batch arrays, which threads then fight over.

These kernels inline much of ``fricenv.core``; their numba cache is keyed on the whole
package's source (``fricenv._numba_cache``), so editing the core recompiles them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from fricenv.core import (
    Solver,
    fresh_workspace,
    initial_mode,
    initial_state,
    reset_stats,
)
from fricenv.core.workspace import W_C1, W_C2, W_PH1, W_PH2, W_S1, W_S2

# The arrays' layouts (declared in .tables; importable from here too).
from fricenv.envs.tables import (  # noqa: F401
    C_ACTION_MODE,
    C_ATOL,
    C_DNU,
    C_DT,
    C_DU,
    C_EFFORT_NORM,
    C_G1,
    C_G2,
    C_INCREMENTAL,
    C_LAW,
    C_LAW_P,
    C_MAX_EVENTS,
    C_METHOD,
    C_NU_HI,
    C_NU_LO,
    C_NU_START,
    C_RTOL,
    C_U0_START,
    C_U_HI,
    C_U_LO,
    C_V_LIM,
    C_W_EFFORT,
    C_W_STICK,
    C_W_VEL,
    C_X_LIM,
    CT_CURSOR,
    CT_STATUS,
    CT_STEPS,
    D_B1,
    D_B3,
    D_ETA,
    D_LAM,
    D_PHI1,
    D_PHI2,
    D_V,
    D_V0,
    D_X0,
    D_XFK,
    D_XFS,
    F_AUTORESET,
    F_DID_RESET,
    F_TERMINATED,
    F_TRUNCATED,
    I_NU,
    I_PHI1,
    I_PHI2,
    I_U0,
    I_V0,
    I_X0,
    IV_MAX_STEPS,
    IV_MODE,
    IV_N_EMPTY,
    IV_N_RESET,
    IV_N_TASKS,
    N_CFG,
    N_COUNTERS,
    N_FLAGS,
    N_INIT,
    N_IVARS,
    N_OBS,
    N_RES,
    N_TABLE,
    O_COS1,
    O_COS2,
    O_NU,
    O_SIN1,
    O_SIN2,
    O_STICK,
    O_U0,
    O_VR,
    O_X,
    OB_FINAL,
    OB_NOW,
    R_EFFORT,
    R_MEAN_VR,
    R_REWARD,
    R_STICK,
    R_TERM,
    R_VAR,
    T_CTRL,
    T_NEW_INIT,
    T_NEW_P,
    T_P,
    T_S,
    T_STATS,
    T_WORK,
)
from fricenv.friction import kernels as friction
from fricenv.jit import kernel
from fricenv.layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    ST_STICK_TIME,
    ST_VR2_INT,
    STATUS_NONFINITE,
)
from fricenv.params import (
    N_LAW_PARAMS,
    P_LAM,
    P_LAW,
    P_LAW_PARAMS,
    P_U1,
    P_U2,
    P_V,
    P_W1,
    P_W2,
    P_XFK,
    P_XFS,
)

# Floor of V^2 in the velocity-fluctuation term (a belt at rest would divide by 0).
V2_FLOOR = 1e-12

# The action modes apply_action tests for (indices into scenes.ACTION_MODES; "both" is 2).
MODE_AMPLITUDE, MODE_FREQUENCY = 0, 1

METHOD_AUTO = -1
TWO_PI = 2.0 * math.pi

# Status returned when an action is not finite (the core's codes are >= 0).
STATUS_BAD_ACTION = -1

# Autoreset modes of the vector kernel.
AUTORESET_NEXT_STEP, AUTORESET_SAME_STEP, AUTORESET_DISABLED = 0, 1, 2



@kernel
def _clip(v, lo, hi):
    return lo if v < lo else (hi if v > hi else v)


@kernel
def actions_finite(a) -> bool:
    for k in range(a.shape[0]):
        if not math.isfinite(a[k]):
            return False
    return True


@kernel
def set_excitation(P, ctrl, cfg) -> None:
    """Write the tone amplitudes and the second tone's frequency from (u0, nu).

    The core accumulates tone phases in the state, so retuning here between two calls of
    ``advance`` keeps every phase continuous.
    """
    P[P_U1] = cfg[C_G1] * ctrl[0]
    P[P_U2] = cfg[C_G2] * ctrl[0]
    P[P_W2] = ctrl[1] * P[P_W1]


@kernel
def apply_action(ctrl, cfg, a) -> None:
    """Map a normalised action in [-1, 1] (clipped) to (u0, nu), absolute or incremental."""
    mode = int(cfg[C_ACTION_MODE])
    incremental = cfg[C_INCREMENTAL] != 0.0
    j = 0
    if mode != MODE_FREQUENCY:
        ai = _clip(np.float64(a[j]), -1.0, 1.0)
        if incremental:
            ctrl[0] = _clip(ctrl[0] + ai * cfg[C_DU], cfg[C_U_LO], cfg[C_U_HI])
        else:
            ctrl[0] = cfg[C_U_LO] + 0.5 * (ai + 1.0) * (cfg[C_U_HI] - cfg[C_U_LO])
        j = 1
    if mode != MODE_AMPLITUDE:
        ai = _clip(np.float64(a[j]), -1.0, 1.0)
        if incremental:
            ctrl[1] = _clip(ctrl[1] + ai * cfg[C_DNU], cfg[C_NU_LO], cfg[C_NU_HI])
        else:
            ctrl[1] = cfg[C_NU_LO] + 0.5 * (ai + 1.0) * (cfg[C_NU_HI] - cfg[C_NU_LO])


@kernel
def _method(P, cfg) -> int:
    m = int(cfg[C_METHOD])
    if m != METHOD_AUTO:
        return m
    if friction.closed_form(P[P_LAW]):
        return METHOD_EXACT
    return METHOD_EVENT


class Plant(NamedTuple):
    """One plant's arrays, as the step kernels pass them on: parameters ``P`` (layout
    ``params.P_*``), state ``S``, excitation setting ``ctrl`` (u0, nu), the last interval's
    ``stats`` and the core's workspace ``work``. Built inside the kernels from their array
    arguments (a record passed from Python costs its call about 0.6 us more to dispatch)."""

    P: np.ndarray
    S: np.ndarray
    ctrl: np.ndarray
    stats: np.ndarray
    work: np.ndarray


@kernel(takes_kernels=True)
def control_interval(advance_ws, plant, cfg, a, res) -> int:
    """Apply action ``a``, advance ``plant`` one control interval by the core's entry
    kernel ``advance_ws`` (see :mod:`fricenv.envs.steppers`), fill the reward terms in
    ``res``.

    Returns the core's status (non-zero: the interval failed and ``res`` is meaningless).
    """
    P = plant.P
    S = plant.S
    stats = plant.stats
    apply_action(plant.ctrl, cfg, a)
    set_excitation(P, plant.ctrl, cfg)
    dt = cfg[C_DT]
    x_start = S[S_X]
    reset_stats(stats)
    solver = Solver(_method(P, cfg), cfg[C_RTOL], cfg[C_ATOL], int(cfg[C_MAX_EVENTS]))
    status = advance_ws(P, S, dt, stats, solver, plant.work)
    if status != 0:
        return status
    V = P[P_V]
    stick = _clip(stats[ST_STICK_TIME] / dt, 0.0, 1.0)
    # Variance of v - V over the interval: the mean of v is exactly (x_end - x_start) / dt.
    mean_vr = (S[S_X] - x_start) / dt - V
    var = stats[ST_VR2_INT] / dt - mean_vr * mean_vr
    if not var > 0.0:
        if math.isnan(var):  # the state is finite but its square overflowed
            return STATUS_NONFINITE
        var = 0.0
    fluct = var / (var + max(V * V, V2_FLOOR))
    effort = (P[P_U1] * P[P_U1] + P[P_U2] * P[P_U2]) * cfg[C_EFFORT_NORM]
    res[R_REWARD] = -(cfg[C_W_STICK] * stick + cfg[C_W_VEL] * fluct + cfg[C_W_EFFORT] * effort)
    res[R_STICK] = stick
    res[R_EFFORT] = effort
    res[R_VAR] = var
    res[R_MEAN_VR] = mean_vr
    return 0


@kernel
def _cos_sin(phi, work, key, c, s):
    """cos and sin of ``phi``, from the core's cache when it holds this very angle."""
    if phi == work[key]:
        return work[c], work[s]
    return math.cos(phi), math.sin(phi)


@kernel
def write_obs(P, S, ctrl, cfg, obs, work) -> bool:
    """Write the float32 observation; True when the state left the observation box.

    The tones' cos/sin come from the core's workspace when it holds them for the phases in
    ``S`` (the closed form carries them), which spares four transcendental calls a step.
    """
    x = S[S_X]
    vr = S[S_V] - P[P_V]
    xl = cfg[C_X_LIM]
    vl = cfg[C_V_LIM]
    c1, s1 = _cos_sin(S[S_PHI1], work, W_PH1, W_C1, W_S1)
    c2, s2 = _cos_sin(S[S_PHI2], work, W_PH2, W_C2, W_S2)
    obs[O_X] = _clip(x, -xl, xl)
    obs[O_VR] = _clip(vr, -vl, vl)
    obs[O_STICK] = 1.0 if S[S_MODE] == 0.0 else 0.0
    obs[O_COS1] = c1
    obs[O_SIN1] = s1
    obs[O_COS2] = c2
    obs[O_SIN2] = s2
    obs[O_U0] = ctrl[0]
    obs[O_NU] = ctrl[1]
    return abs(x) > xl or abs(vr) > vl


@kernel
def start_episode(plant, cfg, P_new, init, obs) -> None:
    """Begin ``plant``'s episode (a :class:`Plant`) from a sampled parameter vector and
    starting vector; write its first observation to ``obs``."""
    P = plant.P
    S = plant.S
    ctrl = plant.ctrl
    for k in range(P.shape[0]):
        P[k] = P_new[k]
    ctrl[0] = init[I_U0]
    ctrl[1] = init[I_NU]
    set_excitation(P, ctrl, cfg)
    initial_state(P, init[I_X0], init[I_V0], S)
    S[S_PHI1] = init[I_PHI1]
    S[S_PHI2] = init[I_PHI2]
    # initial_state chose the mode with zero phases; redo it with the drawn ones.
    S[S_MODE] = initial_mode(P, S[S_X], S[S_V], S[S_PHI1], S[S_PHI2])
    write_obs(P, S, ctrl, cfg, obs, plant.work)


@kernel
def _scaled(u, bounds, k):
    return bounds[0, k] + (bounds[1, k] - bounds[0, k]) * u[k]


@kernel
def _episode_law(cfg, b1, b3, P_out) -> None:
    """An episode's friction law: from its drawn b1, b3 for the paper's laws (cfg[C_LAW]
    = -1), else the scene's law and parameters."""
    law = cfg[C_LAW]
    if law < 0.0:
        P_out[P_LAW] = friction.polynomial_code(b1, b3)
        P_out[P_LAW_PARAMS] = b1
        P_out[P_LAW_PARAMS + 1] = b3
        for i in range(2, N_LAW_PARAMS):
            P_out[P_LAW_PARAMS + i] = 0.0
    else:
        P_out[P_LAW] = law
        for i in range(N_LAW_PARAMS):
            P_out[P_LAW_PARAMS + i] = cfg[C_LAW_P + i]


@kernel
def episode_from_uniforms(u, bounds, cfg, P_out, init_out) -> None:
    """One episode's parameter and starting vectors from its N_DRAWS uniforms ``u``.

    ``bounds`` = [draw_lo, draw_hi]. This is ``EnvSetup.draw``'s scaling followed by
    ``scenes.episode_from_draws`` without options, operation for operation, so that an
    autoreset inside the step kernel starts exactly the episode a single environment's
    ``reset()`` would.
    """
    eta = _scaled(u, bounds, D_ETA)
    u0 = cfg[C_U0_START]
    nu = cfg[C_NU_START]
    P_out[P_LAM] = _scaled(u, bounds, D_LAM)
    P_out[P_V] = _scaled(u, bounds, D_V)
    P_out[P_XFK] = _scaled(u, bounds, D_XFK)
    P_out[P_XFS] = _scaled(u, bounds, D_XFS)
    _episode_law(cfg, _scaled(u, bounds, D_B1), _scaled(u, bounds, D_B3), P_out)
    P_out[P_W1] = eta
    P_out[P_U1] = cfg[C_G1] * u0
    P_out[P_U2] = cfg[C_G2] * u0
    P_out[P_W2] = nu * eta
    init_out[I_X0] = _scaled(u, bounds, D_X0)
    init_out[I_V0] = _scaled(u, bounds, D_V0)
    init_out[I_PHI1] = _scaled(u, bounds, D_PHI1) % TWO_PI
    init_out[I_PHI2] = _scaled(u, bounds, D_PHI2) % TWO_PI
    init_out[I_U0] = u0
    init_out[I_NU] = nu


@kernel(takes_kernels=True)
def step_single_with(advance_ws, P, S, ctrl, cfg, a, stats, obs, res, work) -> int:
    """One step of the single environment (one dispatch per step keeps it cheap: its
    arrays come one by one, which numba dispatches fastest, see :class:`Plant`)."""
    if not actions_finite(a):
        return STATUS_BAD_ACTION
    status = control_interval(advance_ws, Plant(P, S, ctrl, stats, work), cfg, a, res)
    if status != 0:
        return status
    res[R_TERM] = 1.0 if write_obs(P, S, ctrl, cfg, obs, work) else 0.0
    return 0


class Trace(NamedTuple):
    """What ``sample_interval`` writes at each of its instants: time, velocity and whether
    the block sticks."""

    t: np.ndarray
    v: np.ndarray
    stick: np.ndarray


@kernel(takes_kernels=True, allocates=True)
def sample_interval_with(advance, plant, cfg, a, trace) -> int:
    """The coming interval's velocity at ``len(trace.t)`` instants (the renderer's trace
    and ``StickSlipEnv.sample_interval``), by the core's entry kernel ``advance``.

    Works on copies of ``plant`` (its workspace is not read), so sampling never perturbs
    the dynamics of the real step; ``plant.stats`` holds the last piece's statistics.
    """
    Pc = plant.P.copy()
    Sc = plant.S.copy()
    cc = plant.ctrl.copy()
    stats = plant.stats
    apply_action(cc, cfg, a)
    set_excitation(Pc, cc, cfg)
    n = trace.t.shape[0]
    h = cfg[C_DT] / n
    solver = Solver(_method(Pc, cfg), cfg[C_RTOL], cfg[C_ATOL], int(cfg[C_MAX_EVENTS]))
    t0 = Sc[S_T]
    work = fresh_workspace()
    for k in range(n):
        reset_stats(stats)
        status = advance(Pc, Sc, h, stats, solver, work)
        if status != 0:
            return status
        trace.t[k] = t0 + (k + 1) * h
        trace.v[k] = Sc[S_V]
        trace.stick[k] = Sc[S_MODE] == 0.0
    return 0


def empty_cfg() -> np.ndarray:
    return np.zeros(N_CFG)
