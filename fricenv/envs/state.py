"""A plant's full state as a public record: save it, restore it, plan from it.

Model-based control (``fricenv_agents.mpc``) and what-if analysis need to put a plant back where
it was and try other actions. Everything a control interval reads lives in one float64
vector per plant, ``plant``, laid out as the kernels' own arrays (``PL_*``): the episode's
parameter vector (``params.P_*``, the randomised plant and the excitation it runs under),
the state (``layout.S_*``: t, x, v, mode, tone phases), the applied setting (u0, nu) and
the core's workspace. The workspace carries the tones' cos/sin, rotated from one interval
to the next, so a restored plant without them would take its next step through freshly
computed values that differ in the last bits. With them, restoring a state and replaying
the same actions reproduces the trajectory bit for bit, and the batch rollout
(``fricenv.envs.rollout``) starts any number of samples from the same vector without
copying a Python object per sample.

A restored state is held to what ``run_stats`` accepts as a start (one check,
``fricenv.simulate.check_start``), and its workspace is not trusted: every cache in it is
dropped and recomputed from the physical state at the next step (their keys are the
parameters, so the values are the same bits), the environment keeps its own settings
(budget, skipped statistics), and the tones' carried cos/sin are kept only where they are
the cos/sin of the state's phases to within ``TONE_CACHE_TOL``.

Around the plant (``fricenv.envs.sensors``): the actuator's command, the sensors' delay
line, the noise stream's position and the episode's noise scale and delay; and the steps
taken in the episode (the vector env truncates on it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from fricenv.checks import got, is_int, is_real
from fricenv.core.workspace import (
    W_C1,
    W_C2,
    W_MAX_STEPS_CALL,
    W_MAX_STEPS_TAU,
    W_PH1,
    W_PH2,
    W_S1,
    W_S2,
    W_SKIP_EXTREMA,
    W_SKIP_VR2,
)
from fricenv.envs import kernels as K
from fricenv.envs.sensors import check_noise_state
from fricenv.layout import N_STATE, S_MODE, S_PHI1, S_PHI2, S_T, S_V, S_X
from fricenv.params import (
    N_PARAMS,
    P_B1,
    P_B3,
    P_LAM,
    P_U1,
    P_U2,
    P_V,
    P_W1,
    P_W2,
    P_XFK,
    P_XFS,
    OscillatorParams,
)
from fricenv.simulate import OscillatorState, check_start

#: Length of the core's workspace (the vector kernels' table ends with it).
N_WORK = K.N_TABLE - K.T_WORK
# Layout of a plant vector: parameters, state, applied (u0, nu), workspace.
PL_P = 0
PL_S = PL_P + N_PARAMS
PL_CTRL = PL_S + N_STATE
PL_WORK = PL_CTRL + 2
N_PLANT = PL_WORK + N_WORK
#: Workspace slots that are the environment's settings, not the plant's: kept from the
#: environment's own workspace when a state is restored.
_SETTINGS = np.array([W_SKIP_EXTREMA, W_SKIP_VR2, W_MAX_STEPS_TAU, W_MAX_STEPS_CALL])
#: Each tone's phase slot in the state and its cos/sin cache (key, cos, sin) in the workspace.
_TONE_CACHES = ((S_PHI1, W_PH1, W_C1, W_S1), (S_PHI2, W_PH2, W_C2, W_S2))
#: Largest difference a restored tone cache may have from the cos and sin of its phase: the
#: closed form carries them by rotation across intervals, which drifts by about an ulp per
#: step (1e-13 after a million steps); anything further is not a carried value, and the
#: cache is recomputed.
TONE_CACHE_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class PlantState:
    """One plant's full state (see the module docstring); ``get_state()`` returns one,
    ``set_state(state)`` restores it, in an environment made with the same arguments.

    ``plant``: float64 (N_PLANT,) in the ``PL_*`` layout; ``command``: the actuator's
    command (u0, nu) (the applied setting when there is no actuator); ``delay``: the delay
    line of sensor readings, oldest first, float32 (k + 1, 9), or None without sensor
    options; ``noise``: the noise stream (its generator's state and unread normals) or
    None; ``episode_steps``: steps taken since the episode began; ``noise_scale``: the
    factor on the configured noise in this episode; ``obs_delay``: the episode's delay in
    intervals, at most ``k`` (None: ``k``, the delay line's length less one).

    Its arrays are its own (copies both ways), so a state kept stays as it was.
    """

    plant: np.ndarray
    command: np.ndarray
    delay: np.ndarray | None = None
    noise: tuple[Mapping[str, Any] | None, np.ndarray] | None = None
    episode_steps: int = 0
    noise_scale: float = 1.0
    obs_delay: int | None = None

    # -- views of the plant vector ---------------------------------------------------------
    @property
    def t(self) -> float:
        return float(self.plant[PL_S + S_T])

    @property
    def x(self) -> float:
        return float(self.plant[PL_S + S_X])

    @property
    def v(self) -> float:
        return float(self.plant[PL_S + S_V])

    @property
    def mode(self) -> int:
        """-1: slipping slower than the belt, 0: stuck, +1: slipping faster."""
        return int(self.plant[PL_S + S_MODE])

    @property
    def phases(self) -> tuple[float, float]:
        """The two tones' phases in [0, 2 pi)."""
        return float(self.plant[PL_S + S_PHI1]), float(self.plant[PL_S + S_PHI2])

    @property
    def u0(self) -> float:
        """The applied amplitude."""
        return float(self.plant[PL_CTRL])

    @property
    def nu(self) -> float:
        """The applied frequency ratio."""
        return float(self.plant[PL_CTRL + 1])

    @property
    def params(self) -> dict[str, float]:
        """The episode's plant (as ``StickSlipEnv.params``)."""
        P = self.plant[PL_P:PL_S]
        return {"lam": float(P[P_LAM]), "V": float(P[P_V]), "xfk": float(P[P_XFK]),
                "xfs": float(P[P_XFS]), "b1": float(P[P_B1]), "b3": float(P[P_B3]),
                "eta": float(P[P_W1]), "u0": self.u0, "nu": self.nu}

    def same_as(self, other: PlantState) -> bool:
        """True when ``other`` holds the very same bits (workspace, buffers and noise)."""
        def same(a: Any, b: Any) -> bool:
            if a is None or b is None:
                return a is b
            return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()

        if not (same(self.plant, other.plant) and same(self.command, other.command)
                and same(self.delay, other.delay)
                and self.episode_steps == other.episode_steps
                and same(np.float64(self.noise_scale), np.float64(other.noise_scale))
                and self.obs_delay == other.obs_delay):
            return False
        if self.noise is None or other.noise is None:
            return self.noise is other.noise
        return self.noise[0] == other.noise[0] and same(self.noise[1], other.noise[1])


def pack(P: np.ndarray, S: np.ndarray, ctrl: np.ndarray, work: np.ndarray,
         out: np.ndarray | None = None) -> np.ndarray:
    """The plant vector of these arrays (into ``out`` if given)."""
    out = np.empty(N_PLANT) if out is None else out
    out[PL_P:PL_S] = P
    out[PL_S:PL_CTRL] = S
    out[PL_CTRL:PL_WORK] = ctrl
    out[PL_WORK:] = work
    return out


def unpack(plant: np.ndarray, P: np.ndarray, S: np.ndarray, ctrl: np.ndarray,
           work: np.ndarray) -> None:
    """Write a plant vector (checked by ``check_state``) into the environment's arrays.

    The workspace is rebuilt, not copied: the environment's settings stay its own, every
    cache is emptied (the kernels refill them from the parameters, bit for bit as before),
    and a tone's carried cos/sin is taken over only when its key is the state's phase and
    its values are that phase's cos and sin to within ``TONE_CACHE_TOL``.
    """
    P[:] = plant[PL_P:PL_S]
    S[:] = plant[PL_S:PL_CTRL]
    ctrl[:] = plant[PL_CTRL:PL_WORK]
    settings = work[_SETTINGS].copy()
    work[:] = np.nan  # (NaN keys never match: every cache is recomputed)
    work[_SETTINGS] = settings
    given = plant[PL_WORK:]
    for s_phi, key, c, s in _TONE_CACHES:
        phi = S[s_phi]
        if (given[key] == phi and abs(given[c] - np.cos(phi)) <= TONE_CACHE_TOL
                and abs(given[s] - np.sin(phi)) <= TONE_CACHE_TOL):
            work[key], work[c], work[s] = phi, given[c], given[s]


def _check_physics(state: PlantState, dt: float) -> None:
    """``ValueError`` naming the field and value unless the plant and its state are a start
    ``run_stats`` accepts for a run of one control interval ``dt`` (the same check)."""
    P = state.plant[PL_P:PL_S]
    try:
        params = OscillatorParams(
            lam=float(P[P_LAM]), eta=float(P[P_W1]), nu=float(P[P_W2] / P[P_W1]),
            u0=state.u0, V=float(P[P_V]), xfk=float(P[P_XFK]), xfs=float(P[P_XFS]),
            b1=float(P[P_B1]), b3=float(P[P_B3]), u1=float(P[P_U1]), u2=float(P[P_U2]))
    except ValueError as e:
        raise ValueError(f"state holds an invalid plant: {e}") from None
    S = state.plant[PL_S:PL_CTRL]
    start = OscillatorState(float(S[S_T]), float(S[S_X]), float(S[S_V]), state.mode,
                            float(S[S_PHI1]), float(S[S_PHI2]))
    check_start(start, params, dt, "the control interval dt")


def check_state(state: Any, delay_rows: int | None, noisy: bool,
                u_range: tuple[float, float], nu_range: tuple[float, float],
                dt: float) -> None:
    """``TypeError`` / ``ValueError`` naming what is wrong unless ``state`` can be restored
    into an environment whose delay line has ``delay_rows`` rows (None: no sensors), with
    a noise stream or not (``noisy``), these setting ranges and control interval ``dt``;
    the plant and its state are held to ``run_stats``' own check
    (``fricenv.simulate.check_start``)."""
    if not isinstance(state, PlantState):
        raise TypeError(f"state must be a PlantState (from get_state()), {got(state)}")
    for name, arr, shape, dtype in (("plant", state.plant, (N_PLANT,), np.float64),
                                    ("command", state.command, (2,), np.float64)):
        if not (isinstance(arr, np.ndarray) and arr.shape == shape and arr.dtype == dtype):
            raise ValueError(f"state.{name} must be a {np.dtype(dtype)} array of shape "
                             f"{shape}, {got(arr)}")
    core = state.plant[:PL_WORK]  # (the workspace marks empty cache slots with NaN)
    if not np.all(np.isfinite(core)) or not np.all(np.isfinite(state.command)):
        raise ValueError("state holds NaN or infinite values outside the workspace")
    P = state.plant[PL_P:PL_S]
    bad = [k for k, ok in (("lam", P[P_LAM] >= 0.0), ("eta", P[P_W1] > 0.0),
                           ("nu * eta", P[P_W2] >= 0.0), ("xfk", P[P_XFK] >= 0.0),
                           ("xfs", P[P_XFS] >= P[P_XFK])) if not ok]
    if bad:
        raise ValueError(f"state holds an invalid plant ({', '.join(bad)}): {state.params}")
    if state.mode not in (-1, 0, 1) or state.plant[PL_S + S_MODE] != state.mode:
        raise ValueError(f"state.mode must be -1, 0 or 1, got {state.plant[PL_S + S_MODE]!r}")
    _check_physics(state, dt)
    for j, (lo, hi), name in ((0, u_range, "u0"), (1, nu_range, "nu")):
        for arr, what in ((state.plant[PL_CTRL:PL_WORK], "applied"), (state.command, "command")):
            if not lo <= arr[j] <= hi:
                raise ValueError(f"state's {what} {name} = {arr[j]!r} lies outside the "
                                 f"environment's range {(lo, hi)}")
    if (state.delay is None) != (delay_rows is None) or (
            state.delay is not None and state.delay.shape != (delay_rows, K.N_OBS)):
        have = None if state.delay is None else state.delay.shape
        want = None if delay_rows is None else (delay_rows, K.N_OBS)
        raise ValueError(f"state's delay line has shape {have}, this environment's {want}: "
                         "restore a state into an environment made with the same options")
    if state.delay is not None and state.delay.dtype != np.float32:
        raise ValueError(f"state.delay must be float32, got {state.delay.dtype}")
    if state.delay is not None and not np.all(np.isfinite(state.delay)):
        # (readings are clipped to the observation space: a NaN one would reach the
        # agent k steps later, far from the set_state that put it there)
        row, col = (int(i) for i in np.argwhere(~np.isfinite(state.delay))[0])
        raise ValueError(f"state.delay holds a non-finite reading "
                         f"({float(state.delay[row, col])!r} at row {row}, column {col})")
    if (state.noise is None) == noisy:
        raise ValueError("state and environment differ in their noise stream (obs_noise or "
                         "randomize_sensors): restore a state into an environment made "
                         "with the same options")
    if state.noise is not None:
        check_noise_state(state.noise, "state.noise")
    if not isinstance(state.episode_steps, int) or state.episode_steps < 0:
        raise ValueError(f"state.episode_steps must be an int >= 0, {got(state.episode_steps)}")
    _check_sensors(state, delay_rows)


def _check_sensors(state: PlantState, delay_rows: int | None) -> None:
    """``TypeError`` / ``ValueError`` naming the field unless the state's noise scale is a
    real >= 0 and its delay fits the environment's delay line (``delay_rows`` rows)."""
    scale = state.noise_scale
    if not (is_real(scale) and math.isfinite(scale) and scale >= 0.0):
        raise ValueError(f"state.noise_scale must be a finite real >= 0, {got(scale)}")
    most = 0 if delay_rows is None else delay_rows - 1
    lag = state.obs_delay
    if lag is not None and not (is_int(lag) and 0 <= lag <= most):
        raise ValueError(f"state.obs_delay must be None or an int from 0 to the "
                         f"environment's obs_delay = {most}, {got(lag)}")
