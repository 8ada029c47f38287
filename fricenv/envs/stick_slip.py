"""Gymnasium environment: suppress stick-slip of a mass on a moving belt by retuning excitation.

Structured like Gymnasium's classic-control ``pendulum.py``. The physics lives in
``fricenv.core`` (which knows nothing of Gymnasium); one environment step is one call of a
numba kernel (``Steppers.step_single``, built from ``kernels.step_single_with``) that
integrates exactly to the next control instant.
"""

from __future__ import annotations

import math
from typing import Any, Unpack

import gymnasium as gym
import numpy as np

from fricenv.checks import check_int, got, is_int
from fricenv.core import new_workspace
from fricenv.envs import kernels as K
from fricenv.envs.scenes import check_episode_cost, new_episode_arrays
from fricenv.envs.sensors import InstrumentBank, actuate_one, split_sensor_options
from fricenv.envs.settings import EnvKwargs, EnvSettings, settings_signature
from fricenv.envs.setup import ACTION_DTYPES, EnvSetup, coerce_action, raise_status
from fricenv.envs.state import PL_CTRL, PL_P, PL_S, PL_WORK, PlantState, check_state, pack, unpack
from fricenv.envs.steppers import steppers_for, steppers_for_plants
from fricenv.friction.kernels import COULOMB
from fricenv.layout import (
    N_STATE,
    N_STATS,
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    STATUS_DIVERGED,
)
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
    P_XFK,
    P_XFS,
)

#: The single environment's plant in the instruments' (n, ...) arrays.
_PLANT = np.zeros(1, dtype=np.int64)
#: Most instants ``sample_interval`` returns: 17 MB of arrays and a kernel call each, far
#: more than any plot of one control interval needs (n_samples = 1e10 would need 170 GB).
MAX_SAMPLES = 10**6


def check_render_mode(render_mode: Any, modes: list[str]) -> None:
    """``TypeError`` (not a str) or ``ValueError`` (another str) naming ``render_mode`` and
    the allowed ``modes`` unless it is one of them or None."""
    if render_mode is None:
        return
    if not isinstance(render_mode, str):
        raise TypeError(f"render_mode must be one of {list(modes)} or None, {got(render_mode)}")
    if render_mode not in modes:
        raise ValueError(f"render_mode must be one of {list(modes)} or None, "
                         f"got {render_mode!r}")


class RenderModes(list[str]):
    """An environment's ``metadata["render_modes"]``: a list of str whose ``in`` raises the
    ``TypeError`` of :func:`check_render_mode` for anything but a str or None.
    ``gymnasium.make`` tests ``render_mode in render_modes`` before it builds the
    environment, and for a mode not in the list calls ``render_mode.endswith``, which for
    an int is an ``AttributeError`` from inside gymnasium instead of a word on render_mode."""

    def __contains__(self, mode: object) -> bool:
        if mode is not None and not isinstance(mode, str):
            check_render_mode(mode, self)
        return super().__contains__(mode)


class StickSlipEnv(gym.Env):
    r"""
    ## Description

    A block on a belt moving at speed `V` is held by a spring and a damper and driven by
    dry friction; a two-tone force `u0 cos(eta t) + u0 cos(nu eta t)` shakes it (the model of
    "Dry Friction with Various Friction Laws", Modern Mechanical Engineering 5, 2015, Eq. 7,
    in dimensionless time `t`; natural period `2 pi`). Left alone, such a block can
    *stick-slip*: it is carried by the belt until the spring tears it loose, slips back, and
    sticks again. The agent retunes the excitation, its amplitude `u0`, its frequency ratio
    `nu`, or both, once per control interval, to keep the block slipping smoothly with
    little effort.

    The plant is integrated exactly (closed form between events for the Coulomb law, an
    event-locating integrator otherwise), so sticking, which fixed-step schemes smear out,
    is represented faithfully. A scene (``scene=``, see ``fricenv.envs.scenes.SCENES``)
    fixes the plant, the action ranges, the reward weights, the starting state, the
    randomisation ranges and the horizon:

    - `paper` (`fricenv/StickSlip-v0`): the paper's plant (Coulomb law, `lambda = 1/2`,
      `eta = 3/5`, `V = 1`, `x_fk = 2.5`, `x_fs = 4`). The process needs its vibration
      (`u0 = 2`, where `nu = 0.1` makes the block stick about half the time); by default the
      agent retunes `nu` only.
    - `self_excited` (`fricenv/StickSlipSelfExcited-v0`): `lambda = 0.05`, `eta = 6`; the
      block stick-slips with no excitation at all (about 37 % of the time stuck). Some
      `(u0, nu)` quench it, others leave or worsen it; the agent drives both.
    - `stribeck` (`fricenv/StickSlipStribeck-v0`): the paper's complete law, falling near
      the belt speed (`b1 = 0.2`, `b3 = 0.16`), `lambda = 0.1`, `V = 0.3`, `eta = 6`:
      steady sliding is unstable, so the block stick-slips unforced (about 70 % of the time
      stuck); strong enough shaking quenches it, and the instability then regrows slowly.
      The agent drives both settings, `u0` up to 6.
    - `viscous` (`fricenv/StickSlipViscous-v0`): Coulomb plus viscosity (`b1 = 0.2`, a
      friction falling linearly with slip speed), `lambda = 0.1`, `eta = 6`: self-excited
      too (about 46 % stuck unforced); the agent drives both settings, `u0` up to 6.

    The Stribeck and viscous scenes run the event-locating integrator (the closed form
    needs the Coulomb law).

    ## Action Space

    A `Box(-1, 1, (n,), float32)`, scaled inside the environment to the scene's physical
    ranges (out-of-range values are clipped; NaN or inf raises `ValueError`). `action_mode`
    picks the columns:

    | action_mode | Num | Action               | Min | Max | paper    | self_exc.  | others     |
    |-------------|-----|----------------------|-----|-----|----------|------------|------------|
    | amplitude   | 0   | amplitude `u0`       | -1  | 1   | [0, 4]   | [0, 2]     | [0, 6]     |
    | frequency   | 0   | frequency ratio `nu` | -1  | 1   | [0.1, 2] | [0.5, 1.5] | [0.5, 1.5] |
    | both        | 0   | amplitude `u0`       | -1  | 1   | [0, 4]   | [0, 2]     | [0, 6]     |
    | both        | 1   | frequency ratio `nu` | -1  | 1   | [0.1, 2] | [0.5, 1.5] | [0.5, 1.5] |

    (The last three columns are the physical ranges the action is scaled to in the presets:
    paper, self_excited, and stribeck and viscous.)

    Absolute (default): `-1..1` maps linearly onto the range. Incremental
    (``incremental=True``): the action moves the current setting by up to `max_delta`
    (a tenth) of its range per step, clipped to the range. The setting is held during the
    interval (zero-order hold). Each tone's phase is carried over from one interval to the
    next, so retuning `nu` never makes the force jump; a new `u0` scales the tones from the
    current phase on (the state `x`, `v` stays continuous). The dimension not driven by the
    action keeps the scene's starting value.

    ## Observation Space

    A `Box(low, high, (9,), float32)` at the end of each control interval:

    | Num | Observation                                      | Min      | Max     |
    |-----|--------------------------------------------------|----------|---------|
    | 0   | displacement `x` (clipped)                       | -x_limit | x_limit |
    | 1   | velocity relative to the belt `v - V` (clipped)  | -v_limit | v_limit |
    | 2   | stick flag (1: carried by the belt)              | 0        | 1       |
    | 3   | `cos` of tone 1's phase                          | -1       | 1       |
    | 4   | `sin` of tone 1's phase                          | -1       | 1       |
    | 5   | `cos` of tone 2's phase                          | -1       | 1       |
    | 6   | `sin` of tone 2's phase                          | -1       | 1       |
    | 7   | current amplitude `u0`                           | u0 min   | u0 max  |
    | 8   | current frequency ratio `nu`                     | nu min   | nu max  |

    The phases tell the policy where the periodic plant is in its cycle; the current
    settings make incremental control observable. `x_limit = v_limit = 100` in the presets,
    far beyond any bounded motion of the scenes' plants. These are exact values of the
    plant's state; the sensor options (see Arguments) make them noisy, late or partial.

    ## Rewards

    Per control interval of length `dt`:

    *r = -(w_stick * s + w_velocity * q / (q + V^2) + w_effort * e)*

    - `s`: fraction of the interval spent stuck, in [0, 1];
    - `q`: variance of the relative velocity `v - V` over the interval (exact: the integral of
      `(v - V)^2` and the mean `(x_end - x_start) / dt - V`); `q / (q + V^2)` is in [0, 1),
      zero for steady slip;
    - `e = (u1^2 + u2^2) / ((g1^2 + g2^2) u0_max^2)`, the excitation power relative to the
      strongest allowed, in [0, 1] (`u_i = g_i u0`, tone gains `g_i`, both 1 in the presets).

    So `r` lies in `[-(w_stick + w_velocity + w_effort), 0]`; the presets' weights
    `(1, 0.5, 0.1)` give `[-1.6, 0]`. Weights are set by the scene or by ``reward_weights``.
    `info` carries `stick_fraction` (`s`), `effort` (`e`), `velocity_variance` (`q`) and
    `mean_relative_velocity` (the interval's mean of `v - V`).

    ## Starting State

    Displacement `x ~ U(x0_range)` (presets: [-1, 1]), velocity `v ~ U(v0_range)` (presets:
    [-0.5, 0.5], so the block starts slipping against the belt), tone phases `~ U[0, 2 pi)`,
    excitation at the scene's `u0` and `nu` (paper: 2 and 0.1; the others: 0 and 1). With
    ``randomize=True`` the plant parameters are drawn uniformly from the scene's ranges at
    every reset. ``reset(options=...)`` overrides any of `lam, eta, V, xfk, xfs, b1, b3`,
    `x0, v0, phi1, phi2, u0, nu` for that episode (e.g. ``{"x0": 0, "v0": 0, "phi1": 0,
    "phi2": 0}`` is the paper's start from rest). Every reset draws the same number of
    random numbers from `self.np_random`, whatever the options, so seeded runs replay.

    ## Episode End

    - Truncation: by the `TimeLimit` wrapper of `gymnasium.make` after `max_episode_steps`
      (`fricenv/StickSlip-v0`: 200 steps, about 105 time units; `fricenv/StickSlipSelfExcited-v0`:
      400; the Stribeck and viscous ids: 300). The environment itself never truncates.
    - Termination: only if `|x| > x_limit` or `|v - V| > v_limit` (a diverging plant, e.g.
      undamped and resonant through ``reset`` options); never in the presets' ranges.
    - A chattering, too stiff or non-finite integration, or one whose reward overflows
      (a diverging plant, e.g. negative net damping through ``reset`` options, stepped on
      after its termination), raises `RuntimeError` instead of ending silently.

    ## Arguments

    ```python
    >>> import gymnasium as gym, fricenv
    >>> env = gym.make("fricenv/StickSlip-v0", scene="paper", action_mode="both")
    ```

    All but `render_mode` are the fields of ``fricenv.envs.settings.EnvSettings``: give
    them as keywords, or as one record, ``StickSlipEnv(settings=EnvSettings(...))`` (not
    both; `env.settings` is the record an environment was made with).

    - `scene`: `"paper"` (default for `StickSlip-v0`), `"self_excited"`, `"stribeck"`,
      `"viscous"`, or a `Scene`.
      The horizon is the id's `max_episode_steps`: use the scene's own id (or pass
      `max_episode_steps=`) when switching scenes.
    - `action_mode`: `"amplitude"`, `"frequency"` or `"both"` (default: the scene's).
    - `incremental`: actions change the settings instead of setting them (default False; a
      bool, `TypeError` otherwise).
    - `control_dt`: control interval in time units (default pi/6, a twelfth of the natural
      period; at least 1e-6, below which the interval's mean and variance lose their digits).
    - `randomize`: draw the plant parameters per episode from the scene's ranges (a bool).
    - `reward_weights`: `(w_stick, w_velocity, w_effort)` or a dict with those keys.
    - `params`: overrides of the scene's nominal plant, e.g. `{"lam": 0.2}`; with `randomize`,
      a parameter given here keeps its value in every episode. A plant so stiff
      (large `lambda`) or a tone so fast that one control interval would need more than
      `scenes.MAX_INTERVAL_SCAN_STEPS` (1e6) scan steps, seconds per step, is refused with a
      `ValueError` naming its values: at construction (with `randomize`, the ranges' worst
      corner) and, for `reset(options=...)`, at that reset.
    - `method`: `"auto"` (closed form for Coulomb, event integrator otherwise), `"exact"`,
      `"event"`.
    - `render_mode`: `None`, `"rgb_array"` or `"human"`. Frames (block, belt, spring,
      excitation force, velocity over the last 20 time units) are drawn with matplotlib on an
      Agg canvas; `"human"` shows them in a pyplot window when an interactive backend is
      available; without one (headless, or Jupyter without `%matplotlib`) it warns once and
      shows nothing. With `None`, nothing is imported,
      allocated or drawn.

    Sensors and actuator (``fricenv.envs.sensors``; all off by default, and then nothing
    changes; the vector env applies them identically, plant by plant):

    - `obs_noise`: Gaussian noise added to the observation, a standard deviation for every
      channel (a float), nine of them, or a dict such as `{"x": 0.05, "v_rel": 0.1}`
      (channels `x, v_rel, stick, cos1, sin1, cos2, sin2, u0, nu`). Readings are clipped to
      the observation box. The noise comes from a generator spawned from `np_random` at
      each seeding, so seeded runs replay and the episodes' own draws are unchanged.
    - `obs_delay`: the observation is the reading of `k` control intervals earlier (at the
      start of an episode, its first reading).
    - `randomize_sensors`: every episode (the vector env's autoresets too) draws its own
      noise scale, uniform in [0, 1) (multiplying `obs_noise`), and its own delay, uniform
      in `0 .. obs_delay` (`obs_delay` is then the longest). They are drawn from the noise
      stream, `scale = rng.random()` then `rng.integers(0, obs_delay + 1)` as the episode
      starts, so the episodes' own draws stay those of the env without sensors and seeded
      runs replay. Needs `obs_noise` or `obs_delay`; a bool, default False.
    - Reset options `obs_noise_scale` (a real >= 0 multiplying `obs_noise`; refused
      without it) and `obs_delay` (an int from 0 to the configured `obs_delay`) set the
      episode's noise scale and delay, over the draw (without `randomize_sensors`, an
      episode has scale 1 and the configured delay).
    - `observe`: the observed channels, e.g. `("x", "phases")` (displacement and the tones'
      phases, without velocity, stick flag or settings; `"settings"` names `u0, nu`); the
      observation space shrinks to them.
    - `actuator_lag`: the applied `(u0, nu)` follows the commanded one as a first-order lag
      of this time constant (discretised at the control interval); `actuator_rate`: it
      moves at most this fraction of each range per control interval. The plant, the effort
      and the observed `u0, nu` are the applied setting; the action sets the command
      (absolute or incremental, as without an actuator).

    Plant state: `get_state()` returns the plant's full state (a
    ``fricenv.envs.state.PlantState``: `x, v`, mode, `t`, tone phases, applied and commanded
    `u0, nu`, the episode's parameters, the sensors' delay line, noise stream, noise scale
    and delay); `set_state(state)` restores it and returns its observation, so the same
    actions then give the same trajectory bit for bit. ``fricenv.envs.rollout`` rolls out
    many action sequences from one state in one numba call.

    `reset` returns `info = {}`; `step` returns the info described under Rewards.

    ## Version History

    * v0: Initial release. Later additions leave every existing result unchanged: the
      `stribeck` and `viscous` scenes, the sensor and actuator options (off by default),
      `get_state` and `set_state`, the per-episode sensor noise scale and delay
      (`randomize_sensors`, off by default, and the reset options `obs_noise_scale` and
      `obs_delay`).
    """

    metadata = {"render_modes": RenderModes(["human", "rgb_array"]), "render_fps": 12}

    @settings_signature
    def __init__(self, render_mode: str | None = None, *, settings: EnvSettings | None = None,
                 **kwargs: Unpack[EnvKwargs]):
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.setup = EnvSetup.build(EnvSettings.of(settings, kwargs, "StickSlipEnv"))
        self.scene = self.setup.scene
        self.render_mode = render_mode
        self.action_space = self.setup.action_space
        self.observation_space = self.setup.observation_space
        self.dt = self.scene.control_dt

        self._cfg = self.setup.kernel_cfg
        self._P = np.zeros(N_PARAMS)
        self._S = np.zeros(N_STATE)
        self._ctrl = np.zeros(2)
        self._stats = np.zeros(N_STATS)
        self._obs = np.zeros(K.N_OBS, dtype=np.float32)
        self._res = np.zeros(K.N_RES)
        self._work = new_workspace(extrema=False)  # core cache kept across control intervals
        self._P_new, self._init = new_episode_arrays()
        # the entry kernels of the method this episode's plant needs (set at each reset)
        self._steppers = steppers_for_plants(
            self._cfg[K.C_METHOD], self.setup.scene.params.to_array(), self.setup.draw_lo,
            self.setup.draw_hi)
        self._act_shape = self.action_space.shape
        self._needs_reset = True
        self._steps = 0  # since the episode began (part of the plant's state)
        self._bank: InstrumentBank | None = None  # sensors' and actuator's buffers
        self._act: np.ndarray | None = None  # the actuator's parameters, if any
        self._sensing = False
        inst = self.setup.instruments
        if inst is not None:
            full = self.setup.full_observation_space
            self._bank = InstrumentBank(inst, 1, full.low, full.high)
            self._sensing = inst.sensing
            if inst.actuating:
                self._act = inst.actuator_params(self.setup.cfg)
                self._zero_action = np.zeros(self._act_shape)

        self._renderer = None
        if render_mode is not None:
            from fricenv.envs.rendering import Renderer  # lazy: no matplotlib unless asked

            self._renderer = Renderer(render_mode, self.metadata["render_fps"], self.dt)

    @property
    def settings(self) -> EnvSettings:
        """The settings this environment was made with."""
        return self.setup.settings

    # -- Gymnasium API ------------------------------------------------------------------------
    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, float]]:
        if self._needs_reset:
            raise gym.error.ResetNeeded("Cannot call env.step() before calling env.reset()")
        a = action
        if (
            type(a) is not np.ndarray
            or a.shape != self._act_shape
            or a.dtype not in ACTION_DTYPES
            or not a.flags.c_contiguous
        ):
            a = coerce_action(action, self._act_shape)
        if self._act is not None:
            a = self._actuate(a, action)
        if self._renderer is not None:
            self._record_trace(a)
        status = self._steppers.step_single(
            self._P, self._S, self._ctrl, self._cfg, a, self._stats, self._obs, self._res,
            self._work,
        )
        res = self._res
        reward = float(res[K.R_REWARD])
        # NaN exactly when a finite state's (v - V)^2 integral overflowed (the variance is
        # inf); a mean of v - V beyond float64 makes the variance NaN, a status of its own
        if status != 0 or reward != reward:
            if status == 0:
                status = STATUS_DIVERGED
            if status != K.STATUS_BAD_ACTION:
                self._needs_reset = True
            raise_status(status, action)
        self._steps += 1
        bank = self._bank
        if bank is not None and self._sensing:
            bank.push(_PLANT, self._obs[None])
        if self.render_mode == "human":
            self.render()
        # truncated=False: the time limit is the TimeLimit wrapper's job (max_episode_steps).
        return (
            self._observation(),
            reward,
            bool(res[K.R_TERM]),
            False,
            {
                "stick_fraction": float(res[K.R_STICK]),
                "effort": float(res[K.R_EFFORT]),
                "velocity_variance": float(res[K.R_VAR]),
                "mean_relative_velocity": float(res[K.R_MEAN_VR]),
            },
        )

    def reset(
        self, *, seed: int | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict]:
        # A rejected reset loses nothing: the generator is put back as it was before the
        # seeding and the draw (options are checked against the drawn values).
        rng, rng_seed = self._np_random, self._np_random_seed
        state = None if rng is None else rng.bit_generator.state
        super().reset(seed=int(seed) if is_int(seed) else seed)  # numpy ints too
        try:
            plant_options, scale, lag = split_sensor_options(options, self.setup.instruments)
            values = self.setup.draw(self.np_random)
            self.setup.episode(values, plant_options, self._P_new, self._init)
        except BaseException:
            self._np_random, self._np_random_seed = rng, rng_seed
            if rng is not None and state is not None:  # (both or neither)
                rng.bit_generator.state = state
            raise
        K.start_episode(K.Plant(self._P, self._S, self._ctrl, self._stats, self._work),
                        self._cfg, self._P_new, self._init, self._obs)
        self._fit_steppers()
        self._needs_reset = False
        self._steps = 0
        if self._bank is not None:
            self._bank.seed_noise(0, self.np_random)
            self._bank.cmd[0] = self._ctrl
            self._bank.start(_PLANT, self._obs[None], np.array([scale]), np.array([lag]))
        if self._renderer is not None:
            self._renderer.clear(self._S[S_T], self._S[S_V], self._S[S_MODE] == 0.0)
            if self.render_mode == "human":
                self.render()
        return self._observation(), {}

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            # Gymnasium's convention, without needing self.spec (None when built directly).
            env_id = self.spec.id if self.spec is not None else "fricenv/StickSlip-v0"
            gym.logger.warn(
                "You are calling render method without specifying any render mode. "
                "You can specify the render_mode at initialization, "
                f'e.g. gym.make("{env_id}", render_mode="rgb_array") '
                'or StickSlipEnv(render_mode="rgb_array")'
            )
            return None
        assert self._renderer is not None  # made in __init__ whenever render_mode is set
        return self._renderer.render(self.snapshot())

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()

    # -- plant state ----------------------------------------------------------------------------
    def get_state(self) -> PlantState:
        """The plant's full state (``fricenv.envs.state.PlantState``): restoring it with
        ``set_state`` and replaying the same actions reproduces the trajectory bit for bit."""
        if self._needs_reset:
            raise gym.error.ResetNeeded("Cannot call get_state() before calling reset()")
        bank = self._bank
        # (a bank has a delay line exactly when it senses, a command apart from the applied
        # setting exactly when it actuates)
        command = self._ctrl if bank is None or self._act is None else bank.cmd[0]
        sensing = bank is not None and bank.delay is not None
        return PlantState(
            pack(self._P, self._S, self._ctrl, self._work),
            command.copy(),
            None if bank is None or bank.delay is None else bank.delay[0].copy(),
            None if bank is None else bank.noise_state(0),
            self._steps,
            float(bank.scale[0]) if bank is not None and sensing else 1.0,
            int(bank.lag[0]) if bank is not None and sensing else None,
        )

    def set_state(self, state: PlantState) -> np.ndarray:
        """Put the plant in ``state`` (from ``get_state`` of an environment made with the
        same arguments) and return its observation; the next ``step`` continues from there.
        The ``TimeLimit`` wrapper's step count is the wrapper's own and is not touched. A
        plant too costly to step is refused (``ValueError``), as reset options are."""
        bank = self._bank
        check_state(state, None if bank is None or bank.delay is None else bank.delay.shape[1],
                    bank is not None and bank.normals is not None, self.scene.u0_range,
                    self.scene.nu_range, self.dt)
        u0, nu = state.plant[PL_CTRL:PL_WORK].tolist()
        check_episode_cost(self.scene, state.plant[PL_P:PL_S], u0, nu,
                           "refused state: its plant is too stiff or too fast")
        unpack(state.plant, self._P, self._S, self._ctrl, self._work)
        self._fit_steppers()  # (the state's plant may have another damping or law)
        K.write_obs(self._P, self._S, self._ctrl, self._cfg, self._obs, self._work)
        self._steps = state.episode_steps
        if bank is not None:
            bank.cmd[0] = state.command
            if bank.delay is not None:
                bank.delay[0] = state.delay
                bank.restore_sensors(0, state.noise_scale, state.obs_delay)
            bank.set_noise_state(0, state.noise)
        self._needs_reset = False
        if self._renderer is not None:
            self._renderer.clear(self._S[S_T], self._S[S_V], self._S[S_MODE] == 0.0)
        return self._observation()

    # -- helpers ------------------------------------------------------------------------------
    def _fit_steppers(self) -> None:
        """The entry kernels of the episode's plant (see ``steppers_for``)."""
        # within an episode only u0 and nu change, which leave the method's choice alone
        law = self._P[P_LAW] != COULOMB  # (scalars: a reset stays cheap)
        self._steppers = steppers_for(self._cfg[K.C_METHOD], self._P[P_LAM], not law, law)

    def _observation(self) -> np.ndarray:
        """What the agent observes now: the exact observation, or the sensors' reading."""
        bank = self._bank
        if bank is not None and self._sensing:
            return bank.output(_PLANT)[0]
        return self._obs.copy()

    def _actuate(self, a: np.ndarray, action: Any) -> np.ndarray:
        """Move the actuator's command and output by ``a``; the kernel then gets zeros."""
        bank = self._bank
        assert bank is not None  # an actuator (self._act) comes with its buffers
        if not K.actions_finite(a):
            raise_status(K.STATUS_BAD_ACTION, action)
        actuate_one(self._ctrl, bank.cmd[0], self.setup.cfg, a, self._act)
        return self._zero_action

    @property
    def params(self) -> dict[str, float]:
        """The current episode's plant and excitation (after randomisation and options)."""
        P = self._P
        return {
            "lam": float(P[P_LAM]),
            "V": float(P[P_V]),
            "xfk": float(P[P_XFK]),
            "xfs": float(P[P_XFS]),
            "b1": float(P[P_B1]),
            "b3": float(P[P_B3]),
            "eta": float(P[P_W1]),
            "u0": float(self._ctrl[0]),
            "nu": float(self._ctrl[1]),
        }

    def snapshot(self) -> dict[str, float]:
        """What the renderer draws: state, excitation and force now."""
        P, S = self._P, self._S
        g = P[P_U1] * math.cos(S[S_PHI1]) + P[P_U2] * math.cos(S[S_PHI2])
        return {
            "t": float(S[S_T]),
            "x": float(S[S_X]),
            "v": float(S[S_V]),
            "V": float(P[P_V]),
            "stuck": bool(S[S_MODE] == 0.0),
            "u0": float(self._ctrl[0]),
            "nu": float(self._ctrl[1]),
            "force": float(g),
            "xfk": float(P[P_XFK]),
            "x_limit": self.scene.x_limit,
        }

    def sample_interval(
        self, action: np.ndarray, n_samples: int = 64
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The coming control interval under ``action``, without stepping the environment.

        Returns ``(t, v_rel, stuck)`` at ``n_samples`` equally spaced instants ending at the
        next control instant: time, velocity relative to the belt ``v - V``, and whether
        the block is stuck there. Computed on copies of the plant with the step's own
        kernels, in ``n_samples`` pieces (so it matches ``step(action)`` to rounding in
        closed form, to the tolerance with the event method), and the environment's state
        is left untouched (for plotting a policy's motion, as the renderer does).
        ``n_samples`` is an integer from 1 to ``MAX_SAMPLES`` (``ValueError`` beyond).
        """
        if self._needs_reset:
            raise gym.error.ResetNeeded("Cannot call sample_interval() before calling reset()")
        n = check_int("n_samples", n_samples, 1, MAX_SAMPLES)
        a = coerce_action(action, self._act_shape)
        if not K.actions_finite(a):
            raise_status(K.STATUS_BAD_ACTION, action)
        t, v = np.empty(n), np.empty(n)
        stuck = np.empty(n, dtype=np.bool_)
        ctrl = self._ctrl
        bank = self._bank
        if bank is not None and self._act is not None:
            # the setting the actuator would apply, on copies
            ctrl = ctrl.copy()
            actuate_one(ctrl, bank.cmd[0].copy(), self.setup.cfg, a, self._act)
            a = self._zero_action
        status = self._sample_into(a, t, v, stuck, ctrl)
        if status != 0:
            raise_status(status, action)
        return t, v - self._P[P_V], stuck

    def _sample_into(self, a: np.ndarray, t: np.ndarray, v: np.ndarray,
                     stuck: np.ndarray, ctrl: np.ndarray | None = None) -> int:
        ctrl = self._ctrl if ctrl is None else ctrl
        plant = K.Plant(self._P, self._S, ctrl, self._stats, self._work)
        return self._steppers.sample_interval(plant, self._cfg, a, K.Trace(t, v, stuck))

    def _record_trace(self, a: np.ndarray) -> None:
        r = self._renderer
        assert r is not None  # called only when rendering
        if not K.actions_finite(a):
            return  # the step itself raises
        if self._sample_into(a, r.buf_t, r.buf_v, r.buf_s) == 0:
            r.push()
