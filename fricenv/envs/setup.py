"""What an environment derives from its settings, and the checks its steps share.

``EnvSetup.build`` turns an ``EnvSettings`` (``fricenv.envs.settings``: what
``StickSlipEnv``, ``StickSlipVectorEnv`` and the SB3 adapter are made with) into the
scene, the spaces and the kernels' configuration, once, so that every environment reads
them alike; ``raise_status`` and ``coerce_action`` are the
error and action paths their steps have in common. A module of its own so that neither
environment's module carries the other's construction.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from fricenv.checks import check_bool, check_dict, check_real, real_array, real_tuple
from fricenv.core.constants import MAX_STEPS_PER_TAU
from fricenv.envs import kernels as K
from fricenv.envs.channels import OBSERVATION, Limits
from fricenv.envs.scenes import (
    ACTION_MODES,
    N_DRAWS,
    THREE_WEIGHTS,
    Scene,
    episode_from_draws,
    get_scene,
)
from fricenv.envs.sensors import Instruments
from fricenv.envs.settings import EnvSettings
from fricenv.friction import closed_form_rows, polynomial_laws_in
from fricenv.layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    STATUS_DIVERGED,
    STATUS_EVENT_CAP,
    STATUS_NONFINITE,
    STATUS_STEP_BUDGET,
    STATUS_TOO_STIFF,
)
from fricenv.params import N_LAW_PARAMS, P_LAW

_METHODS = {"auto": K.METHOD_AUTO, "exact": METHOD_EXACT, "event": METHOD_EVENT}
_WEIGHT_KEYS = ("stick", "velocity", "effort")
#: Action dtypes the kernels are compiled for; any other goes through ``coerce_action``.
ACTION_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))

#: Solver settings of the environments: tight enough that integration error is far below
#: anything a policy could exploit, loose enough to keep a step cheap.
RTOL = 1e-8
ATOL = 1e-10
#: Events (stick/slip/reversal) allowed per control interval before the run is declared
#: chattering (a Zeno-like plant; it raises rather than silently stalling).
MAX_EVENTS = 10_000


@dataclass(frozen=True)
class EnvSetup:
    """Everything the single and the vector environment derive from their settings."""

    #: the settings it was built from (``EnvSettings``, as given)
    settings: EnvSettings
    scene: Scene
    action_mode: str
    incremental: bool
    randomize: bool
    cfg: np.ndarray
    action_space: spaces.Box
    observation_space: spaces.Box
    draw_lo: np.ndarray
    draw_hi: np.ndarray
    #: sensor and actuator options (None: the exact observation, the setting applied at
    #: once), the configuration the kernels run with (``Instruments.kernel_cfg``; ``cfg``
    #: itself without instruments) and the nine-channel observation box the sensors clip to
    instruments: Instruments | None
    kernel_cfg: np.ndarray
    full_observation_space: spaces.Box

    @classmethod
    def build(cls, settings: EnvSettings | str | Scene = "paper", **kwargs: Any) -> EnvSetup:
        """The setup of ``settings`` (an ``EnvSettings``), or of a scene and the other
        settings as keywords: ``EnvSetup.build("paper", obs_delay=2)``. Every value is
        checked here; an error names the setting and the value."""
        if isinstance(settings, EnvSettings):
            if kwargs:
                raise TypeError("EnvSetup.build takes an EnvSettings or a scene and keywords, "
                                f"not both (got keywords {sorted(kwargs)})")
        else:
            settings = EnvSettings.from_kwargs({"scene": settings, **kwargs}, "EnvSetup.build")
        st = settings
        sc = get_scene(st.scene)
        instruments = Instruments.build(st.obs_noise, st.obs_delay, st.observe,
                                        st.actuator_lag, st.actuator_rate,
                                        st.randomize_sensors)
        # bools only: a truthy string such as 'no' would switch the mode on
        incremental = check_bool("incremental", st.incremental)
        randomize = check_bool("randomize", st.randomize)
        sc = _changed_scene(sc, st, randomize)
        method = st.method
        if not isinstance(method, str):
            raise TypeError(f"method must be one of {sorted(_METHODS)}, got {method!r}")
        if method not in _METHODS:
            raise ValueError(f"method must be one of {sorted(_METHODS)}, got {method!r}")
        # (b1, b3 drawn only when randomising; reset(options=...) checks its own episode)
        drawn = sc.ranges if randomize else {}
        if method == "exact" and (
            not sc.params.is_coulomb
            or "cubic" in polynomial_laws_in(drawn.get("b1", (0.0, 0.0)),
                                             drawn.get("b3", (0.0, 0.0)))
        ):
            raise ValueError(f"method='exact' needs the Coulomb law (b1 = b3 = 0), got the "
                             f"{sc.params.law_spec.name} law"
                             + (" with b1, b3 randomised" if sc.params.is_coulomb else ""))
        # Every episode drawn without options (the vector env's autoresets included) stays
        # within what this checks; reset(options=...) checks its own plant.
        sc.check_interval_cost(randomize)
        cfg = _kernel_cfg(sc, incremental, method)

        n_act = 2 if sc.action_mode == "both" else 1
        (ulo, uhi), (nlo, nhi) = sc.u0_range, sc.nu_range
        action_space = spaces.Box(-1.0, 1.0, shape=(n_act,), dtype=np.float32)
        low, high = OBSERVATION.box(Limits(sc.x_limit, sc.v_limit, (ulo, uhi), (nlo, nhi)))
        full_space = spaces.Box(low, high, dtype=np.float32)
        observation_space: spaces.Box = full_space
        kernel_cfg = cfg
        if instruments is not None:
            observation_space = instruments.observation_space(full_space)
            kernel_cfg = instruments.kernel_cfg(cfg)
        draw_lo, draw_hi = sc.draw_bounds(randomize)
        return cls(
            settings=settings,
            scene=sc,
            action_mode=sc.action_mode,
            incremental=incremental,
            randomize=randomize,
            cfg=cfg,
            action_space=action_space,
            observation_space=observation_space,
            draw_lo=draw_lo,
            draw_hi=draw_hi,
            instruments=instruments,
            kernel_cfg=kernel_cfg,
            full_observation_space=full_space,
        )

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """The uniforms of one episode, scaled; always N_DRAWS numbers from ``rng``."""
        return self.scale(rng.random(N_DRAWS))

    def scale(self, u: np.ndarray) -> np.ndarray:
        """One episode's N_DRAWS uniforms scaled to their bounds (``kernels._scaled`` is
        the same expression, for episodes started inside the vector kernel)."""
        return self.draw_lo + (self.draw_hi - self.draw_lo) * u

    def episode(self, values: np.ndarray, options: dict | None, P_out, init_out) -> None:
        episode_from_draws(self.scene, values, options, P_out, init_out)
        if self.cfg[K.C_METHOD] == METHOD_EXACT and not closed_form_rows(P_out[P_LAW]):
            raise ValueError("method='exact' needs the Coulomb law (b1 = b3 = 0)")


def _changed_scene(sc: Scene, st: EnvSettings, randomize: bool) -> Scene:
    """Scene ``sc`` with the changes the other settings of ``st`` make."""
    params = st.params
    changes: dict[str, Any] = {}
    check_dict("params", params, "a dict of plant parameters, e.g. {'lam': 0.2},")
    if params:
        changes["params"] = sc.params.replace(**params)
        # a value given explicitly is kept for every episode, not drawn over
        changes["randomization"] = tuple(
            (k, r) for k, r in sc.randomization if k not in params)
    if not randomize and sc.randomization:
        # ranges never drawn from are not checked against the plant either (a plant with
        # params={"xfs": 2.5} is valid whatever x_fk's range would allow)
        changes["randomization"] = ()
    if st.action_mode is not None:
        changes["action_mode"] = st.action_mode
    if st.control_dt is not None:
        changes["control_dt"] = check_real("control_dt", st.control_dt)
    if st.reward_weights is not None:
        changes["reward_weights"] = _reward_weights(st.reward_weights, sc.reward_weights)
    return sc.replace(**changes) if changes else sc


def _kernel_cfg(sc: Scene, incremental: bool, method: str) -> np.ndarray:
    """The kernels' configuration vector (``kernels.C_*``) of scene ``sc``."""
    cfg = K.empty_cfg()
    (ulo, uhi), (nlo, nhi) = sc.u0_range, sc.nu_range
    g1, g2 = sc.tone_gains
    cfg[K.C_DT] = sc.control_dt
    cfg[K.C_ACTION_MODE] = ACTION_MODES.index(sc.action_mode)
    cfg[K.C_INCREMENTAL] = 1.0 if incremental else 0.0
    cfg[K.C_U_LO], cfg[K.C_U_HI] = ulo, uhi
    cfg[K.C_NU_LO], cfg[K.C_NU_HI] = nlo, nhi
    cfg[K.C_DU] = sc.max_delta * (uhi - ulo)
    cfg[K.C_DNU] = sc.max_delta * (nhi - nlo)
    cfg[K.C_G1], cfg[K.C_G2] = g1, g2
    cfg[K.C_W_STICK], cfg[K.C_W_VEL], cfg[K.C_W_EFFORT] = sc.reward_weights
    cfg[K.C_EFFORT_NORM] = 1.0 / ((g1 * g1 + g2 * g2) * uhi * uhi)
    cfg[K.C_X_LIM], cfg[K.C_V_LIM] = sc.x_limit, sc.v_limit
    cfg[K.C_METHOD] = _METHODS[method]
    cfg[K.C_RTOL], cfg[K.C_ATOL], cfg[K.C_MAX_EVENTS] = RTOL, ATOL, MAX_EVENTS
    cfg[K.C_U0_START], cfg[K.C_NU_START] = sc.params.u0, sc.params.nu
    law = sc.params.to_array()[P_LAW:]
    cfg[K.C_LAW] = -1.0 if sc.params.friction is None else law[0]
    cfg[K.C_LAW_P:K.C_LAW_P + N_LAW_PARAMS] = law[1:]
    return cfg


def _reward_weights(value: Any, current: tuple[float, ...]) -> tuple[float, ...]:
    """The ``reward_weights`` argument as three floats; a dict overrides the named ones of
    ``current`` (the scene's)."""
    what = f"{THREE_WEIGHTS} or a dict with keys {', '.join(map(repr, _WEIGHT_KEYS))}"
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(_WEIGHT_KEYS), key=repr)
        if unknown:
            raise ValueError(f"unknown reward weight(s) {unknown}; expected {_WEIGHT_KEYS}")
        for key, w in value.items():
            check_real(f"reward_weights[{key!r}]", w)
        merged = dict(zip(_WEIGHT_KEYS, current, strict=True))
        merged.update(value)
        value = tuple(merged[k] for k in _WEIGHT_KEYS)
    return real_tuple("reward_weights", value, 3, what)


def raise_status(status: int, action: Any, where: str = "") -> None:
    """Turn a kernel status into the exception a user can act on."""
    if status == K.STATUS_BAD_ACTION:
        raise ValueError(f"action{where} must be finite (no NaN or inf), got {action!r}")
    if status == STATUS_EVENT_CAP:
        raise RuntimeError(
            f"plant{where} chattered: more than {MAX_EVENTS} stick/slip events in one control "
            "interval; reset the environment (check the parameters passed at make/reset)"
        )
    if status == STATUS_NONFINITE:
        raise RuntimeError(f"plant{where} state became NaN or infinite; reset the environment")
    if status == STATUS_TOO_STIFF:
        raise RuntimeError(f"plant{where}: slip too stiff for the integrator's smallest step "
                           "(check the parameters passed at make/reset); reset the environment")
    if status == STATUS_STEP_BUDGET:
        raise RuntimeError(
            f"plant{where}: the control interval needed more integrator steps than the budget "
            f"allows ({MAX_STEPS_PER_TAU:g} in a unit of tau): slip far faster than the "
            "model's scale or a state far from it (check the parameters "
            "passed at make/reset); reset the environment")
    if status == STATUS_DIVERGED:
        raise RuntimeError(f"plant{where} diverged: the state is finite but the interval's "
                           "(v - V)^2 integral overflowed, leaving no reward (negative net "
                           "damping? check the parameters passed at make/reset); reset the "
                           "environment")
    raise RuntimeError(f"plant{where}: integrator failed with status {status}")


def coerce_action(
    action: Any, shape: tuple[int, ...], name: str = "action", batch: bool = False
) -> np.ndarray:
    """Slow path for actions that are not a C-contiguous float32/float64 ndarray of shape
    ``shape``: a float64 copy of ``shape`` (any layout of the same number of values; with
    ``batch``, one whose first axis is ``shape[0]``, the plants, so that a transposed batch
    is refused rather than read as other plants' actions).

    ``TypeError`` unless ``action`` is made of real numbers (None, strings, dicts, complex
    would otherwise turn into NaN, a float or a numba typing error), ``ValueError`` for the
    wrong number of values; both name ``name`` and the value. NaN and inf pass: the kernels
    reject them without touching the plant.
    """
    want = f"{name} must be an array of real numbers of shape {shape}"
    a = real_array(action, want)
    if a.size != math.prod(shape) or (batch and (a.ndim == 0 or a.shape[0] != shape[0])):
        raise ValueError(f"{want}, got shape {a.shape}: {action!r}")
    return np.ascontiguousarray(a.reshape(shape), dtype=np.float64)
