"""Plants, observations and actions on batches: the public maps between them.

Model-based controllers and estimators (``fricenv_agents.mpc``, ``fricenv_agents.estimation``)
work on many plant vectors at once (``fricenv.envs.state``: one float64 row per plant) and
need the environments' own maps between those plants, the observations the agent sees and
the actions it gives. They live here, once, vectorised over rows, so that no controller
keeps a copy of them or indexes a plant vector by slot:

- :class:`Plants`: named columns of a table of plant vectors (views: writes go through);
- :func:`observe`: the exact, noise-free observation of plants, as the kernels write it;
- :func:`check_observations`: ``ValueError`` naming the row, channel and value of a batch
  that no environment of a setup can give;
- :func:`plants_from_observations`: plants estimated from full observations;
- :func:`initial_modes`: stick or slip of states, by the core's own rule;
- :func:`actions_towards`: the normalised actions that move settings towards targets.

The channels themselves (names, order, bounds) are declared in :mod:`fricenv.envs.channels`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fricenv.core import new_workspace
from fricenv.envs import kernels as K
from fricenv.envs.channels import CHANNELS, OBSERVATION
from fricenv.envs.setup import EnvSetup
from fricenv.envs.state import N_PLANT, PL_CTRL, PL_P, PL_S, PL_WORK
from fricenv.envs.tables import DRAWS, RANDOMIZABLE
from fricenv.friction import LAWS
from fricenv.jit import kernel
from fricenv.layout import S_MODE, S_PHI1, S_PHI2, S_T, S_V, S_X
from fricenv.params import P_B1, P_B3, P_LAM, P_LAW, P_U1, P_U2, P_V, P_W1, P_W2, P_XFK, P_XFS

TWO_PI = 2.0 * np.pi
#: Column of each named plant parameter in a plant vector's parameter block: the
#: randomisable ones (``tables.RANDOMIZABLE``; ``eta`` is the first tone's frequency) and
#: what the setting drives (``u1``, ``u2``: the tones' amplitudes; ``w2``: the second
#: tone's frequency, ``nu * eta``).
PARAMETERS: dict[str, int] = {"lam": P_LAM, "eta": P_W1, "V": P_V, "xfk": P_XFK,
                              "xfs": P_XFS, "b1": P_B1, "b3": P_B3, "u1": P_U1, "u2": P_U2,
                              "w2": P_W2}
__all__ = ["CHANNELS", "OBSERVATION", "PARAMETERS", "RANDOMIZABLE", "Plants",
           "actions_towards", "channel_names", "check_observations", "draw_ranges",
           "fresh_workspace", "initial_modes", "observe", "plants_from_observations",
           "setting_ranges", "setting_start"]
_STATE = {"t": S_T, "x": S_X, "v": S_V, "mode": S_MODE, "phi1": S_PHI1, "phi2": S_PHI2}


class Plants:
    """Named columns of a table of plant vectors ``(m, N_PLANT)`` (``fricenv.envs.state``).

    Every column is a view of the table, so ``plants.x += dx`` moves the table's x.
    ``params`` is the parameter block (m, N_PARAMS), ``param(name)`` one parameter
    (:data:`PARAMETERS`), ``setting`` the applied ``(u0, nu)`` (m, 2), ``workspace`` the
    core's workspace. ``Plants.new(m)`` makes a zeroed table.
    """

    def __init__(self, table: np.ndarray):
        if not (isinstance(table, np.ndarray) and table.ndim == 2
                and table.shape[1] == N_PLANT and table.dtype == np.float64):
            raise ValueError(f"plants must be a float64 array (m, {N_PLANT}), got "
                             f"{getattr(table, 'dtype', type(table).__name__)} "
                             f"{getattr(table, 'shape', '')}")
        self.table = table

    @classmethod
    def new(cls, m: int) -> Plants:
        return cls(np.zeros((m, N_PLANT)))

    def __len__(self) -> int:
        return self.table.shape[0]

    def _col(self, offset: int) -> np.ndarray:
        return self.table[:, offset]

    def _set(self, offset: int, values: Any) -> None:
        self.table[:, offset] = values

    # -- state ------------------------------------------------------------------------------
    t = property(lambda self: self._col(PL_S + S_T),
                 lambda self, v: self._set(PL_S + S_T, v), doc="time")
    x = property(lambda self: self._col(PL_S + S_X),
                 lambda self, v: self._set(PL_S + S_X, v), doc="displacement")
    v = property(lambda self: self._col(PL_S + S_V),
                 lambda self, v: self._set(PL_S + S_V, v), doc="velocity")
    mode = property(lambda self: self._col(PL_S + S_MODE),
                    lambda self, v: self._set(PL_S + S_MODE, v),
                    doc="-1/+1 slipping below/above the belt, 0 stuck")
    phi1 = property(lambda self: self._col(PL_S + S_PHI1),
                    lambda self, v: self._set(PL_S + S_PHI1, v), doc="first tone's phase")
    phi2 = property(lambda self: self._col(PL_S + S_PHI2),
                    lambda self, v: self._set(PL_S + S_PHI2, v), doc="second tone's phase")
    u0 = property(lambda self: self._col(PL_CTRL),
                  lambda self, v: self._set(PL_CTRL, v), doc="applied amplitude")
    nu = property(lambda self: self._col(PL_CTRL + 1),
                  lambda self, v: self._set(PL_CTRL + 1, v), doc="applied frequency ratio")

    @property
    def V(self) -> np.ndarray:
        """The belt speed (a parameter, named for the state's sake: v - V)."""
        return self._col(PL_P + P_V)

    @property
    def params(self) -> np.ndarray:
        return self.table[:, PL_P:PL_S]

    @params.setter
    def params(self, values: Any) -> None:
        self.table[:, PL_P:PL_S] = values

    @property
    def setting(self) -> np.ndarray:
        return self.table[:, PL_CTRL:PL_WORK]

    @property
    def workspace(self) -> np.ndarray:
        return self.table[:, PL_WORK:]

    @workspace.setter
    def workspace(self, values: Any) -> None:
        self.table[:, PL_WORK:] = values

    def param(self, name: str) -> np.ndarray:
        """Parameter ``name`` (:data:`PARAMETERS`) of every plant, a view."""
        return self._col(PL_P + _parameter(name))

    def set_param(self, name: str, values: Any) -> None:
        """Set parameter ``name`` of every plant; b1 and b3 also set the law of a plant of
        the paper's laws (Coulomb where both are 0, else cubic), as ``OscillatorParams``
        does."""
        self._set(PL_P + _parameter(name), values)
        if name in ("b1", "b3"):
            law = self._col(PL_P + P_LAW)
            paper = np.isin(law, _PAPER_CODES)
            coulomb = (self.param("b1") == 0.0) & (self.param("b3") == 0.0)
            self._set(PL_P + P_LAW, np.where(
                paper, np.where(coulomb, LAWS["coulomb"].code, LAWS["cubic"].code), law))

    def state(self, name: str) -> np.ndarray:
        """State quantity ``name`` (t, x, v, mode, phi1, phi2), a view."""
        if name not in _STATE:
            raise ValueError(f"unknown state quantity {name!r}; expected one of {list(_STATE)}")
        return self._col(PL_S + _STATE[name])

    def drive(self, tone_gains: tuple[float, float]) -> None:
        """Tune every plant to its applied setting, as a control interval does
        (``kernels.set_excitation``): u1 = g1 u0, u2 = g2 u0, w2 = nu eta."""
        g1, g2 = tone_gains
        self.set_param("u1", g1 * self.u0)
        self.set_param("u2", g2 * self.u0)
        self.set_param("w2", self.nu * self.param("eta"))

    def settle_modes(self) -> None:
        """Each plant's mode from its state (:func:`initial_modes`)."""
        self.mode = initial_modes(self.params, self.x, self.v, self.phi1, self.phi2)


_PAPER_CODES = (LAWS["coulomb"].code, LAWS["cubic"].code)


def _parameter(name: str) -> int:
    if name not in PARAMETERS:
        raise ValueError(f"unknown plant parameter {name!r}; expected one of "
                         f"{list(PARAMETERS)}")
    return PARAMETERS[name]


_initial_mode = K.initial_mode


@kernel
def _initial_modes(P, x, v, phi1, phi2, out) -> None:
    for i in range(x.shape[0]):
        out[i] = _initial_mode(P[i], x[i], v[i], phi1[i], phi2[i])


def initial_modes(params: np.ndarray, x: Any, v: Any, phi1: Any, phi2: Any) -> np.ndarray:
    """The mode (m,) of each state: -1/+1 slipping below/above the belt, 0 stuck (v == V
    and the force within the static level), by the core's own rule
    (``fricenv.core.state.initial_mode``) on rows of parameter vectors ``params``."""
    P = np.ascontiguousarray(params, dtype=np.float64)
    m = P.shape[0]

    def column(a: Any) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=np.float64), (m,)))

    out = np.empty(m)
    _initial_modes(P, column(x), column(v), column(phi1), column(phi2), out)
    return out


def observe(plants: np.ndarray | Plants, setup: EnvSetup) -> np.ndarray:
    """The exact, noise-free full observations (m, 9), float64, of plant vectors (m,
    N_PLANT) in environments of ``setup``: what ``kernels.write_obs`` writes (x and v - V
    clipped to the box), before the sensors and the float32 rounding."""
    p = plants if isinstance(plants, Plants) else Plants(plants)
    cfg = setup.cfg
    out = np.empty((len(p), K.N_OBS))
    out[:, K.O_X] = np.clip(p.x, -cfg[K.C_X_LIM], cfg[K.C_X_LIM])
    out[:, K.O_VR] = np.clip(p.v - p.V, -cfg[K.C_V_LIM], cfg[K.C_V_LIM])
    out[:, K.O_STICK] = p.mode == 0.0
    out[:, K.O_COS1], out[:, K.O_SIN1] = np.cos(p.phi1), np.sin(p.phi1)
    out[:, K.O_COS2], out[:, K.O_SIN2] = np.cos(p.phi2), np.sin(p.phi2)
    out[:, K.O_U0:] = p.setting
    return out


def channel_names(setup: EnvSetup) -> list[str]:
    """The names of the channels an environment of ``setup`` observes, in order."""
    inst = setup.instruments
    return OBSERVATION.describe(None if inst is None else inst.channels)


def check_observations(obs: Any, setup: EnvSetup) -> np.ndarray:
    """``obs`` as a float64 batch (n, m) of observations an environment of ``setup`` can
    give; ``ValueError`` naming the row, the channel and the value otherwise: an empty
    batch, the wrong number of channels, NaN or inf, a value outside the observation box
    (the sensors clip to it, noise included), or a stick flag other than 0 or 1 where the
    flag is read without noise."""
    a = np.asarray(obs, dtype=np.float64)
    names = channel_names(setup)
    if a.ndim == 1:
        a = a.reshape(1, -1)
    if a.ndim != 2 or a.shape[1] != len(names):
        raise ValueError(f"observations must have shape ({len(names)},) or (n, {len(names)}) "
                         f"(channels {names}), got {np.shape(obs)}")
    if a.shape[0] == 0:
        raise ValueError(f"an empty batch of observations (shape {np.shape(obs)}): "
                         "need at least one")
    box = setup.observation_space
    bad = ~np.isfinite(a) | (a < box.low) | (a > box.high)
    inst = setup.instruments
    if "stick" in names and (inst is None or inst.noise is None
                             or inst.noise[CHANNELS.index("stick")] == 0.0):
        s = names.index("stick")
        bad[:, s] |= (a[:, s] != 0.0) & (a[:, s] != 1.0)
    if bad.any():
        i, j = (int(k) for k in np.argwhere(bad)[0])
        stick_only = (names[j] == "stick" and np.isfinite(a[i, j])
                      and box.low[j] <= a[i, j] <= box.high[j])
        what = ("0 or 1: a stick flag read without noise" if stick_only else
                f"finite and within [{box.low[j]:g}, {box.high[j]:g}]")
        given = np.asarray(obs).reshape(a.shape)[i, j]  # (as given: float32 prints short)
        raise ValueError(f"observation {i}, channel {names[j]!r} = {str(given)}: no "
                         f"environment of this setup gives it (must be {what})")
    return a


def plants_from_observations(obs: np.ndarray, params: np.ndarray,
                             tone_gains: tuple[float, float]
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Plant vectors and commands (n, N_PLANT), (n, 2) estimated from full observations
    ``obs`` (n, 9) of plants with the parameter vector ``params`` (``params.P_*``).

    For a controller that has only the observation: x, v - V, the stick flag (read as
    stuck above 0.5; a stuck plant has v = V exactly), the tones' phases from their cos and
    sin, and the settings. The time is set to 0 (the plant is autonomous given the phases)
    and the workspace is empty, so a plan made from it starts from the observation's
    float32 precision, not the plant's exact state.
    """
    obs = np.asarray(obs, dtype=np.float64)
    n = obs.shape[0]
    p = Plants.new(n)
    p.params = params
    p.u0, p.nu = obs[:, K.O_U0], obs[:, K.O_NU]
    p.drive(tone_gains)
    p.t = 0.0
    p.x = obs[:, K.O_X]
    V = p.V
    p.v = np.where(obs[:, K.O_STICK] > 0.5, V, obs[:, K.O_VR] + V)
    p.phi1 = np.arctan2(obs[:, K.O_SIN1], obs[:, K.O_COS1]) % TWO_PI
    p.phi2 = np.arctan2(obs[:, K.O_SIN2], obs[:, K.O_COS2]) % TWO_PI
    p.settle_modes()
    p.workspace = fresh_workspace(n)
    return p.table, p.setting.copy()


def actions_towards(setup: EnvSetup, target: Sequence[Any], current: Sequence[Any]
                    ) -> np.ndarray:
    """The normalised actions (n, n_act), float32, that move the settings ``current``
    ``(u0, nu)`` (arrays (n,)) towards ``target`` ``(u0, nu)`` under ``setup``'s action
    map (``kernels.apply_action``): absolute actions reach a target within the ranges at
    once; incremental ones move as fast as the largest step allows. Only the settings the
    action mode drives get a column."""
    cfg = setup.cfg
    incremental = setup.incremental
    cols = []
    n = np.shape(current[0])[0]
    for j, drives, lo, hi, step in (
            (0, setup.action_mode != "frequency", cfg[K.C_U_LO], cfg[K.C_U_HI], cfg[K.C_DU]),
            (1, setup.action_mode != "amplitude", cfg[K.C_NU_LO], cfg[K.C_NU_HI],
             cfg[K.C_DNU])):
        if not drives:
            continue
        goal = np.broadcast_to(target[j], (n,))
        if incremental:
            cols.append(np.clip((goal - current[j]) / step, -1.0, 1.0))
        else:
            cols.append(np.clip(2.0 * (np.clip(goal, lo, hi) - lo) / (hi - lo) - 1.0,
                                -1.0, 1.0))
    return np.stack(cols, axis=1).astype(np.float32)


def setting_ranges(setup: EnvSetup) -> dict[str, tuple[float, float]]:
    """The ranges ``(lo, hi)`` of the settings ``u0`` and ``nu`` under ``setup``."""
    cfg = setup.cfg
    return {"u0": (cfg[K.C_U_LO], cfg[K.C_U_HI]), "nu": (cfg[K.C_NU_LO], cfg[K.C_NU_HI])}


def setting_start(setup: EnvSetup) -> tuple[float, float]:
    """The setting ``(u0, nu)`` an episode of ``setup`` starts from."""
    cfg = setup.cfg
    return cfg[K.C_U0_START], cfg[K.C_NU_START]


def draw_ranges(setup: EnvSetup) -> dict[str, tuple[float, float]]:
    """Where an episode of ``setup`` draws each quantity: the randomisable parameters
    (:data:`RANDOMIZABLE`, a one-point range where not randomised) and the starting
    state (``x0``, ``v0``, ``phi1``, ``phi2``), by name, in the order they are drawn."""
    return {name: (setup.draw_lo[k], setup.draw_hi[k])
            for name, k, _ in DRAWS.slots}


def fresh_workspace(n: int | None = None) -> np.ndarray:
    """An empty core workspace (one, or ``n`` rows) for plants assembled by hand: every
    cache empty, the environments' settings."""
    return new_workspace(n, extrema=False)
