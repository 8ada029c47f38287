"""Named scenes: a plant, its actuator, its reward and its horizon, bundled for the RL envs.

A scene is everything that makes a control *task* out of the oscillator: the nominal
parameters, the physical ranges the normalised action is scaled to, the reward weights, the
episode horizon, the starting-state distribution and the ranges for per-episode domain
randomisation. Environments read a scene once at construction, so swapping scenes never
touches the kernels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from fricenv.checks import (
    check_bool,
    check_bounded_real,
    check_dict,
    check_int,
    check_real,
    got,
    real_tuple,
)
from fricenv.envs.ids import HORIZONS
from fricenv.envs.tables import (  # noqa: F401  (the draws' order and starting vector)
    I_NU,
    I_PHI1,
    I_PHI2,
    I_U0,
    I_V0,
    I_X0,
    INITIAL,
    N_DRAWS,
    N_INIT,
    RANDOMIZABLE,
)
from fricenv.friction import polynomial_law
from fricenv.params import (
    N_PARAMS,
    P_B1,
    P_B3,
    P_LAM,
    P_LAW,
    P_U1,
    P_U2,
    P_V,
    P_W1,
    P_W2,
    P_XFK,
    P_XFS,
    PARAM_LIMIT,
    OscillatorParams,
    check_known_fields,
)
from fricenv.simulate import check_scan_steps

#: Action modes: which excitation settings the agent drives.
ACTION_MODES = ("amplitude", "frequency", "both")

#: Keys ``reset(options=...)`` accepts: plant parameters, starting state, starting excitation.
OPTION_KEYS = (*RANDOMIZABLE, *INITIAL, "u0", "nu")


TWO_PI = 2.0 * math.pi

#: What ``reward_weights`` holds, for error messages.
THREE_WEIGHTS = "three weights (w_stick, w_velocity, w_effort)"

#: Shortest control interval. The step's mean velocity and variance are differences over it,
#: (x_end - x_start) / dt and the mean of (v - V)^2 less the mean's square, so they keep
#: about log10(dt / 1e-16) digits, and time itself resolves only ~1e-13 max(1, |t|): at
#: dt = 1e-12 the variance is rounding noise of about 3e-3, at 1e-300 the mean reads 2e284.
MIN_CONTROL_DT = 1e-6

#: Most scan steps one control interval may need (``core.most_scan_steps``, the kernels' own
#: bound). A step costs about 60 ns, so this is some 60 ms per ``env.step``; an over-damped
#: plant (the step is 1 / lam) or a very fast tone beyond it would make every step take
#: seconds (lam = 1e8: 5e7 scan steps, ~3 s), which is more likely a typo than a plant.
MAX_INTERVAL_SCAN_STEPS = 1e6


def _pair(name: str, value: Any) -> tuple[float, float]:
    lo, hi = real_tuple(name, value, 2, "a finite (lo, hi) with lo <= hi")
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ValueError(f"{name} must be a finite (lo, hi) with lo <= hi, got {value!r}")
    for bound in (lo, hi):
        check_bounded_real(name, bound, PARAM_LIMIT)  # (as every parameter)
    return lo, hi


@dataclass(frozen=True)
class Scene:
    """A control task on the oscillator (see the module docstring).

    ``params.u0`` and ``params.nu`` are the excitation the episode starts with (and keeps in
    the dimension the action mode does not drive). ``tone_gains`` scale u0 per tone, so
    ``(1, 0)`` is a single tone. Ranges are ``(lo, hi)``; a randomisation range applies only
    when the environment is made with ``randomize=True``.
    """

    name: str
    description: str
    params: OscillatorParams
    u0_range: tuple[float, float]
    nu_range: tuple[float, float]
    action_mode: str = "both"
    tone_gains: tuple[float, float] = (1.0, 1.0)
    #: control interval in tau: a twelfth of the natural period 2 pi (>= 0.5; see
    #: docs/environments.md)
    control_dt: float = math.pi / 6.0
    max_episode_steps: int = 200
    #: weights of (stick fraction, relative-velocity fluctuation, effort) in the cost
    reward_weights: tuple[float, float, float] = (1.0, 0.5, 0.1)
    #: incremental actions: largest change per step, as a fraction of each range
    max_delta: float = 0.1
    x0_range: tuple[float, float] = (-1.0, 1.0)
    v0_range: tuple[float, float] = (-0.5, 0.5)
    random_phase: bool = True
    #: observation clip for |x| and |v - V|; leaving it terminates the episode
    x_limit: float = 100.0
    v_limit: float = 100.0
    #: ranges ``{param: (lo, hi)}`` (given as a dict; stored as a tuple of pairs so that a
    #: scene stays hashable, copyable and picklable)
    randomization: Any = ()

    def __post_init__(self) -> None:
        if not isinstance(self.params, OscillatorParams):
            raise TypeError(f"params must be an OscillatorParams, {got(self.params)}")
        if not isinstance(self.action_mode, str):
            raise TypeError(f"action_mode must be one of {ACTION_MODES}, {got(self.action_mode)}")
        if self.action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {self.action_mode!r}")
        for name in ("u0_range", "nu_range", "x0_range", "v0_range"):
            object.__setattr__(self, name, _pair(name, getattr(self, name)))
        (ulo, uhi), (nlo, nhi) = self.u0_range, self.nu_range
        if not (0.0 <= ulo < uhi):
            raise ValueError(f"u0_range must satisfy 0 <= lo < hi, got {self.u0_range}")
        if not (0.0 <= nlo < nhi):
            raise ValueError(f"nu_range must satisfy 0 <= lo < hi, got {self.nu_range}")
        if not ulo <= self.params.u0 <= uhi:
            raise ValueError(f"params.u0 = {self.params.u0} lies outside u0_range {self.u0_range}")
        if not nlo <= self.params.nu <= nhi:
            raise ValueError(f"params.nu = {self.params.nu} lies outside nu_range {self.nu_range}")
        self.params.replace(u0=uhi, nu=nhi)  # the top of the action ranges: a valid plant
        if self.params.u1 is not None or self.params.u2 is not None:
            raise ValueError("scene params must not set u1/u2; use tone_gains")
        gains = real_tuple("tone_gains", self.tone_gains, 2, "two gains >= 0, not both 0")
        if min(gains) < 0.0 or max(gains) == 0.0:
            raise ValueError(f"tone_gains must be two gains >= 0, not both 0, got {gains}")
        object.__setattr__(self, "tone_gains", gains)
        weights = real_tuple("reward_weights", self.reward_weights, 3, THREE_WEIGHTS)
        if not all(math.isfinite(w) and w >= 0.0 for w in weights):
            raise ValueError(f"reward_weights must be three finite weights >= 0, got {weights}")
        object.__setattr__(self, "reward_weights", weights)
        for name in ("control_dt", "max_delta", "x_limit", "v_limit"):
            check_real(name, getattr(self, name))
        object.__setattr__(self, "max_episode_steps",
                           check_int("max_episode_steps", self.max_episode_steps, 1))
        object.__setattr__(self, "random_phase", check_bool("random_phase", self.random_phase))
        checks = (
            ("control_dt", math.isfinite(self.control_dt) and self.control_dt >= MIN_CONTROL_DT),
            ("max_delta", 0.0 < self.max_delta <= 1.0),
            ("x_limit", self.x_limit > 0.0),
            ("v_limit", self.v_limit > 0.0),
        )
        for name, ok in checks:
            if not ok:
                rule = f" (at least {MIN_CONTROL_DT:g})" if name == "control_dt" else ""
                raise ValueError(f"{name} is out of range{rule}, got {getattr(self, name)!r}")
        rnd = {}
        for key, value in _randomization_items(self.randomization):
            if key not in RANDOMIZABLE:
                raise ValueError(f"cannot randomise {key!r}; expected some of {RANDOMIZABLE}")
            rnd[key] = _pair(f"randomization[{key!r}]", value)
        ordered = tuple((k, rnd[k]) for k in RANDOMIZABLE if k in rnd)
        object.__setattr__(self, "randomization", ordered)
        # Every corner of the randomisation box must be a valid plant, so that a sampled
        # episode never needs validating at reset time.
        for corner in ({k: v[0] for k, v in rnd.items()}, {k: v[1] for k, v in rnd.items()}):
            try:
                self.params.replace(**corner)
            except ValueError as e:
                raise ValueError(f"the randomization corner {corner} makes an invalid plant "
                                 f"with the scene's parameters ({e}): narrow the ranges or "
                                 "change the parameters") from None
        if "xfk" in rnd or "xfs" in rnd:
            xfk_hi = rnd.get("xfk", (self.params.xfk,) * 2)[1]
            xfs_lo = rnd.get("xfs", (self.params.xfs,) * 2)[0]
            if xfs_lo < xfk_hi:
                raise ValueError("randomization must keep xfs >= xfk: xfs lo < xfk hi")

    def check_interval_cost(self, randomize: bool = True, cap: float = MAX_INTERVAL_SCAN_STEPS,
                            context: str = "") -> None:
        """``ValueError`` naming the values if the fastest plant an episode of this scene can
        start from its draws (the nominal one, or with ``randomize`` the worst corner of the
        randomisation box: ``lam`` and ``eta`` at the top of their ranges) needs more than
        ``cap`` (default ``MAX_INTERVAL_SCAN_STEPS``) scan steps in a control interval,
        under the fastest excitation its actions can reach (:func:`check_episode_cost`;
        ``context`` opens the message's remedy).

        Called when an environment is built (not at scene construction, which stays free of
        numba calls): episodes drawn without options, including those the vector env starts
        inside its kernel, then never need the check; ``reset(options=...)`` checks its own.
        """
        if randomize:
            plant = self.params.replace(**{k: hi for k, (_, hi) in self.randomization})
            why = ("the scene's fastest plant (lam and eta at the top of their randomization "
                   "ranges) is too stiff or too fast: narrow those ranges or lower the top "
                   "of nu_range")
        else:
            plant = self.params
            why = "the scene's plant is too stiff or too fast: lower lam, eta or nu_range's top"
        check_episode_cost(self, plant.to_array(), self.params.u0, self.params.nu,
                           context + why, cap)

    @property
    def ranges(self) -> dict[str, tuple[float, float]]:
        """The randomisation ranges as a dict."""
        return dict(self.randomization)

    def replace(self, **changes: Any) -> Scene:
        """A copy with ``changes`` applied (validated like a new scene)."""
        check_known_fields(self, changes, "scene field")
        return replace(self, **changes)

    # -- sampling ---------------------------------------------------------------------------
    def draw_bounds(self, randomize: bool) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the N_DRAWS uniforms an episode consumes.

        Without randomisation the parameter bounds collapse to the nominal value, so the number
        of draws (and hence the random stream) is the same either way.
        """
        lo = np.empty(N_DRAWS)
        hi = np.empty(N_DRAWS)
        ranges = self.ranges if randomize else {}
        for k, name in enumerate(RANDOMIZABLE):
            nominal = float(getattr(self.params, name))
            lo[k], hi[k] = ranges.get(name, (nominal, nominal))
        k = len(RANDOMIZABLE)
        lo[k], hi[k] = self.x0_range
        lo[k + 1], hi[k + 1] = self.v0_range
        phase_hi = TWO_PI if self.random_phase else 0.0
        lo[k + 2 : k + 4] = 0.0
        hi[k + 2 : k + 4] = phase_hi
        return lo, hi


def _randomization_items(value: Any) -> list[tuple[Any, Any]]:
    """The ``(param, range)`` items of a scene's ``randomization``: a dict (or None), or the
    tuple of pairs a scene stores it as (what ``replace`` passes back); ``TypeError`` naming
    it otherwise, rather than ``dict()``'s own error."""
    if isinstance(value, tuple) and all(
        isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str) for item in value
    ):
        return list(value)
    check_dict("randomization", value, "a dict {param: (lo, hi)}")
    return list(value.items()) if value is not None else []


def check_episode_cost(scene: Scene, P: np.ndarray, u0: float, nu: float, why: str,
                       cap: float = MAX_INTERVAL_SCAN_STEPS) -> None:
    """``ValueError`` naming the values if an episode of ``scene`` with the plant ``P``
    (layout ``params.P_*``; or one such row per plant), started at excitation ``(u0, nu)``,
    could need more than ``cap`` (default ``MAX_INTERVAL_SCAN_STEPS``) scan steps in one
    control interval: the fastest excitation its actions reach is the top of the range of
    each setting the action mode drives (the other keeps its start). One mechanism with
    the simulator's cap, ``simulate.check_scan_steps``; ``why`` ends the message."""
    if scene.action_mode in ("amplitude", "both"):
        u0 = scene.u0_range[1]
    if scene.action_mode in ("frequency", "both"):
        nu = scene.nu_range[1]
    rows = np.array(P, dtype=np.float64, ndmin=2)
    rows[:, P_U1] = scene.tone_gains[0] * u0
    rows[:, P_U2] = scene.tone_gains[1] * u0
    rows[:, P_W2] = nu * rows[:, P_W1]
    dt = scene.control_dt
    check_scan_steps(rows, np.full(rows.shape[0], dt),
                     f"that span is one control interval (control_dt) at u0 = {u0:.6g}, "
                     f"nu = {nu:.6g}; {why}", cap=cap)


def episode_from_draws(
    scene: Scene, values: np.ndarray, options: dict | None, P_out: np.ndarray, init_out: np.ndarray
) -> None:
    """Fill the parameter vector and starting vector of one episode.

    ``values`` are the drawn quantities (already scaled to their bounds) in the order
    RANDOMIZABLE + INITIAL. ``options`` (from ``reset(options=...)``) override any of them and
    the starting excitation; an override is validated, so a bad one fails at reset.
    """
    check_dict("options", options)
    vals = dict(zip((*RANDOMIZABLE, *INITIAL), values.tolist(), strict=True))
    u0, nu = scene.params.u0, scene.params.nu
    if options:
        unknown = sorted(set(options) - set(OPTION_KEYS))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; expected some of {OPTION_KEYS}")
        for key, value in options.items():
            # TypeError for a non-number (complex would pass as np.number, cut to its real
            # part), ValueError for NaN, inf or a magnitude beyond PARAM_LIMIT (a start at
            # x0 = 1e200 overflowed the reward to NaN)
            vals[key] = check_bounded_real(f"reset option {key!r}", value, PARAM_LIMIT)
        # Validates the plant (raises ValueError naming the field).
        plant = scene.params.replace(**{k: vals[k] for k in RANDOMIZABLE})
        u0 = float(options.get("u0", u0))
        nu = float(options.get("nu", nu))
        (ulo, uhi), (nlo, nhi) = scene.u0_range, scene.nu_range
        if not ulo <= u0 <= uhi:
            raise ValueError(f"reset option u0 = {u0} lies outside u0_range {scene.u0_range}")
        if not nlo <= nu <= nhi:
            raise ValueError(f"reset option nu = {nu} lies outside nu_range {scene.nu_range}")
        # Draws alone stay in the ranges the environment checked when it was built.
        check_episode_cost(scene, plant.to_array(), u0, nu, f"refused reset options {options!r}")
    P_out[P_LAM] = vals["lam"]
    P_out[P_V] = vals["V"]
    P_out[P_XFK] = vals["xfk"]
    P_out[P_XFS] = vals["xfs"]
    if scene.params.friction is None:  # (kernels._episode_law, operation for operation)
        P_out[P_LAW] = polynomial_law(vals["b1"], vals["b3"]).code
        P_out[P_B1] = vals["b1"]
        P_out[P_B3] = vals["b3"]
        P_out[P_B3 + 1:] = 0.0
    else:
        P_out[P_LAW:] = scene.params.to_array()[P_LAW:]
    P_out[P_W1] = vals["eta"]
    # The excitation slots are written by the kernels from (u0, nu) and the tone gains.
    P_out[P_U1] = scene.tone_gains[0] * u0
    P_out[P_U2] = scene.tone_gains[1] * u0
    P_out[P_W2] = nu * vals["eta"]
    init_out[I_X0] = vals["x0"]
    init_out[I_V0] = vals["v0"]
    init_out[I_PHI1] = vals["phi1"] % TWO_PI
    init_out[I_PHI2] = vals["phi2"] % TWO_PI
    init_out[I_U0] = u0
    init_out[I_NU] = nu


def new_episode_arrays() -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(N_PARAMS), np.zeros(N_INIT)


# -- presets --------------------------------------------------------------------------------
_PLANT_RANDOMIZATION = {"V": (0.8, 1.2), "xfk": (2.2, 2.8), "xfs": (3.6, 4.4)}

SCENES: dict[str, Scene] = {
    "paper": Scene(
        name="paper",
        description=(
            "The paper's plant (Coulomb law, lambda = 1/2, eta = 3/5, V = 1, x_fk = 2.5, "
            "x_fs = 4) under its two-tone excitation. The process needs the vibration "
            "(u0 = 2 at the start, where nu = 0.1 gives stick phases); the agent retunes the "
            "frequency ratio, and with action_mode='both' also the amplitude, to avoid sticking."
        ),
        params=OscillatorParams.preset("coulomb", u0=2.0, nu=0.1),
        u0_range=(0.0, 4.0),
        nu_range=(0.1, 2.0),
        action_mode="frequency",
        max_episode_steps=HORIZONS["paper"],
        reward_weights=(1.0, 0.5, 0.1),
        x0_range=(-1.0, 1.0),
        v0_range=(-0.5, 0.5),
        randomization={"lam": (0.4, 0.6), **_PLANT_RANDOMIZATION},
    ),
    "self_excited": Scene(
        name="self_excited",
        description=(
            "A lightly damped plant (Coulomb law, lambda = 0.05) that stick-slips with no "
            "excitation at all (about 37 % of the time stuck). Two tones at eta = 6 and "
            "nu * eta can quench it (in phase, nu = 1 and u0 = 1 add up to the single tone of "
            "amplitude 2 known to leave no stick), while other settings leave or worsen it. "
            "Once quenched, the unforced plant can also coast without sticking."
        ),
        params=OscillatorParams.preset("coulomb", lam=0.05, eta=6.0, u0=0.0, nu=1.0),
        u0_range=(0.0, 2.0),
        nu_range=(0.5, 1.5),
        action_mode="both",
        max_episode_steps=HORIZONS["self_excited"],
        reward_weights=(1.0, 0.5, 0.1),
        x0_range=(-1.0, 1.0),
        v0_range=(-0.5, 0.5),
        randomization={"lam": (0.03, 0.08), **_PLANT_RANDOMIZATION},
    ),
    "stribeck": Scene(
        name="stribeck",
        description=(
            "The paper's complete law with its falling (Stribeck-like) characteristic "
            "(b1 = 0.2, b3 = 0.16) on a slow belt (V = 0.3) and a light damper (lambda = "
            "0.1): friction falls faster with slip speed than the damper rises, so steady "
            "sliding is unstable and the block stick-slips with no excitation at all (about "
            "70 % of the time stuck). Shaking at eta = 6 hard enough (from about u0 = 3.5 on "
            "both tones with nu = 1, or nu = 0.5) leaves no stick in steady state, weaker or "
            "detuned shaking only part of it; once quenched, the instability regrows slowly "
            "(e-folding about 35 time units), so the excitation can rest for a while."
        ),
        params=OscillatorParams.preset("stribeck", lam=0.1, V=0.3, eta=6.0, u0=0.0, nu=1.0),
        u0_range=(0.0, 6.0),
        nu_range=(0.5, 1.5),
        max_episode_steps=HORIZONS["stribeck"],
        # every corner keeps the sliding unstable: lam - b1 + 3 b3 V^2 < 0 up to lam = 0.13
        # with V = 0.35
        randomization={"lam": (0.07, 0.13), "V": (0.25, 0.35), "xfk": (2.2, 2.8),
                       "xfs": (3.6, 4.4)},
    ),
    "viscous": Scene(
        name="viscous",
        description=(
            "Coulomb friction plus the paper's viscous term (b1 = 0.2), which falls linearly "
            "with slip speed, on a lightly damped plant (lambda = 0.1 < b1): steady sliding "
            "is unstable and the block stick-slips unforced (about 46 % of the time stuck). "
            "In steady state, shaking at eta = 6 with u0 of 2 to 3 leaves a few per cent, "
            "u0 = 4.5 on both tones with nu = 1 (or nu = 0.5) none; weaker shaking leaves or "
            "worsens it."
        ),
        params=OscillatorParams.preset("viscous", lam=0.1, eta=6.0, u0=0.0, nu=1.0),
        u0_range=(0.0, 6.0),
        nu_range=(0.5, 1.5),
        max_episode_steps=HORIZONS["viscous"],
        # lam stays below b1 = 0.2 in every corner: the sliding stays unstable
        randomization={"lam": (0.05, 0.15), **_PLANT_RANDOMIZATION},
    ),
    "exponential": Scene(
        name="exponential",
        description=(
            "The exponential Stribeck law (x_fs = 4 at break-away, falling to x_fk = 2.5 "
            "past the Stribeck speed vs = 0.4 as a Gaussian, delta = 2, with viscosity cv "
            "= 0.05) on a slow belt (V = 0.3) and a light damper (lambda = 0.1). Friction is "
            "continuous at break-away, and falls with slip speed far faster than the damper "
            "rises around the block's sliding speed, so the block stick-slips with no "
            "excitation at all. Shaking at eta = 6 can quench it."
        ),
        params=OscillatorParams.preset("exponential", lam=0.1, V=0.3, eta=6.0, u0=0.0,
                                       nu=1.0),
        u0_range=(0.0, 6.0),
        nu_range=(0.5, 1.5),
        max_episode_steps=HORIZONS["exponential"],
        randomization={"lam": (0.07, 0.13), "V": (0.25, 0.35), "xfk": (2.2, 2.8),
                       "xfs": (3.6, 4.4)},
    ),
}


def get_scene(scene: str | Scene) -> Scene:
    """The scene named ``scene`` (or ``scene`` itself); ``ValueError`` listing the names."""
    if isinstance(scene, Scene):
        return scene
    if not isinstance(scene, str):
        raise TypeError(f"scene must be a scene name or a Scene, {got(scene)}")
    try:
        return SCENES[str(scene)]
    except KeyError:
        raise ValueError(f"unknown scene {scene!r}; expected one of {sorted(SCENES)}") from None
