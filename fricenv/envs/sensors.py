"""Sensors and actuators between the agent and the plant, as they really are.

The environments' kernels give the agent the plant's exact state and apply its setting at
once. A real rig measures with noise, late and not everything, and its shaker follows a
command with a lag and a slew-rate limit. These options model that around the kernel
calls, identically in the single and the vector environment (both run the code below on
``(n, ...)`` arrays, ``n = 1`` for the single one), so seeded runs stay bit-identical and
the vector env matches the single env with every option on. All are off by default, and
off they cost nothing and change nothing.

Sensor chain, per observation: the kernel's exact observation -> plus Gaussian noise of a
standard deviation per channel -> clipped to the observation box (a sensor saturates at its
range; it also keeps the observation inside the space) -> a delay line of ``k`` control
intervals -> the chosen channels. The noise comes from a child of the env's ``np_random``
(``Generator.spawn``, at each new seeding): spawning draws nothing from the parent, so the
episodes' own draws (parameters, start) are those of a noise-free env, and the vector env
can keep buffering them ahead (its per-plant generators spawn children the same way).
Normals are drawn ``NOISE_ROWS`` observations at a time.

Per episode, each plant has a noise scale (multiplying the configured standard
deviations; 1 by default) and a delay ``k`` in ``0 .. obs_delay`` (``obs_delay`` by
default). The delay line always holds ``obs_delay + 1`` readings; a plant delayed ``k``
reads the one ``k`` intervals old. With ``randomize_sensors`` every episode (the vector
env's autoresets too) draws them from the plant's noise stream as it starts, before its
first reading: ``scale = rng.random()`` (uniform in [0, 1)), then
``k = rng.integers(0, obs_delay + 1)``, both drawn whatever the reset options say, so the
stream's position depends on the number of episodes only. The reset options
``obs_noise_scale`` and ``obs_delay`` set them for one episode (over the draw).

Actuator, per control interval: the action commands a setting ``(u0, nu)`` exactly as
without an actuator (absolute or incremental, ``kernels.apply_action``, on the command);
the applied setting then moves towards the command, by a first-order lag (time constant
``actuator_lag``, discretised at the control interval: a fraction ``1 - exp(-dt / lag)``
of the gap per interval) and at most ``actuator_rate`` of each range per interval. The
plant, the effort and the observed ``u0``, ``nu`` are the applied setting. The kernels
then run with an incremental configuration and zero actions, which leaves the applied
setting exactly as written (``clip(s + 0 * du) = s``), so no kernel changes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from fricenv.checks import check_bool, check_dict, check_finite_real, check_int, got, items_of
from fricenv.envs import kernels as K
from fricenv.envs.channels import CHANNEL_GROUPS, CHANNELS
from fricenv.jit import kernel

#: Observations' worth of standard normals drawn per plant at a time.
NOISE_ROWS = 64
#: Longest observation delay, in control intervals (the delay line is copied every step).
MAX_DELAY = 1000
#: The reset options of the sensors (``split_sensor_options``).
SENSOR_OPTIONS = ("obs_noise_scale", "obs_delay")
#: "Not given" in the per-plant arrays of sensor options: no scale, no delay.
NO_SCALE = math.nan
NO_DELAY = -1

# Layout of the actuator's parameter vector: the lag's fraction of the gap closed per
# interval (1: no lag), then the largest change per interval of u0 and of nu (inf: none).
A_ALPHA, A_RATE_U, A_RATE_NU = range(3)
N_ACT_PARAMS = 3


# -- option parsing -------------------------------------------------------------------------
def _noise_vector(value: Any) -> np.ndarray | None:
    """``obs_noise`` as nine standard deviations, or None when it adds nothing."""
    if value is None:
        return None
    std = np.zeros(K.N_OBS)
    what = ("obs_noise must be a standard deviation (applied to every channel), nine of "
            f"them, or a dict {{channel: std}} with channels from {CHANNELS}")
    if isinstance(value, Mapping):
        for key, sd in value.items():
            if key not in CHANNELS:
                raise ValueError(f"obs_noise: unknown channel {key!r}; expected some of "
                                 f"{CHANNELS}")
            std[CHANNELS.index(key)] = check_finite_real(f"obs_noise[{key!r}]", sd)
    elif (items := items_of(value)) is not None:
        if len(items) != K.N_OBS:
            raise ValueError(f"{what}, got {len(items)} values: {value!r}")
        for i, sd in enumerate(items):
            std[i] = check_finite_real(f"obs_noise[{i}]", sd)
    else:
        try:
            std[:] = check_finite_real("obs_noise", value)
        except TypeError:
            raise TypeError(f"{what}, {got(value)}") from None
    if np.any(std < 0.0):
        raise ValueError(f"obs_noise standard deviations must be >= 0, got {value!r}")
    return std if np.any(std > 0.0) else None


def _channels(value: Any) -> tuple[int, ...] | None:
    """``observe`` as sorted channel indices, or None for all of them."""
    if value is None:
        return None
    names = [value] if isinstance(value, str) else items_of(value)
    if names is None:
        raise TypeError(f"observe must be channel names from {CHANNELS} (or "
                        f"{sorted(CHANNEL_GROUPS)}), {got(value)}")
    picked: list[int] = []
    for name in names:
        if not isinstance(name, str):
            raise TypeError(f"observe must name channels by str, {got(name)}")
        group = CHANNEL_GROUPS.get(name, (name,))
        for ch in group:
            if ch not in CHANNELS:
                raise ValueError(f"observe: unknown channel {name!r}; expected some of "
                                 f"{CHANNELS} or {sorted(CHANNEL_GROUPS)}")
            if CHANNELS.index(ch) in picked:
                raise ValueError(f"observe names channel {ch!r} twice: {value!r}")
            picked.append(CHANNELS.index(ch))
    if not picked:
        raise ValueError("observe must name at least one channel")
    chosen = tuple(sorted(picked))
    return None if chosen == tuple(range(K.N_OBS)) else chosen


@dataclass(frozen=True, eq=False)
class Instruments:
    """The sensor and actuator options of an environment (see the module docstring).

    ``noise``: nine standard deviations (None: no noise); ``delay``: intervals;
    ``channels``: observed channel indices (None: all nine); ``lag``: the actuator's time
    constant (0: none); ``rate``: its largest change per interval as a fraction of each
    range (None: none); ``randomize``: each episode draws its noise scale and delay.
    """

    noise: np.ndarray | None = None
    delay: int = 0
    channels: tuple[int, ...] | None = None
    lag: float = 0.0
    rate: float | None = None
    randomize: bool = False

    @classmethod
    def build(cls, obs_noise: Any = None, obs_delay: Any = 0, observe: Any = None,
              actuator_lag: Any = 0.0, actuator_rate: Any = None,
              randomize_sensors: Any = False) -> Instruments | None:
        """The options as given to the environments, checked; None when all are off."""
        noise = _noise_vector(obs_noise)
        delay = check_int("obs_delay", obs_delay, 0, MAX_DELAY)
        randomize = check_bool("randomize_sensors", randomize_sensors)
        if randomize and noise is None and delay == 0:
            raise ValueError("randomize_sensors=True draws each episode's noise scale and "
                             "delay, so it needs obs_noise or obs_delay > 0 (got neither)")
        channels = _channels(observe)
        lag = check_finite_real("actuator_lag", actuator_lag)
        if lag < 0.0:
            raise ValueError(f"actuator_lag must be a time constant >= 0, got {actuator_lag!r}")
        rate = None
        if actuator_rate is not None:
            rate = check_finite_real("actuator_rate", actuator_rate)
            if not 0.0 < rate <= 1.0:
                raise ValueError("actuator_rate must be the largest change per control "
                                 "interval as a fraction of each range, in (0, 1], got "
                                 f"{actuator_rate!r}")
        inst = cls(noise, delay, channels, lag, rate, randomize)
        return inst if (inst.sensing or inst.actuating) else None

    @property
    def sensing(self) -> bool:
        return self.noise is not None or self.delay > 0 or self.channels is not None

    @property
    def actuating(self) -> bool:
        return self.lag > 0.0 or self.rate is not None

    def describe(self) -> dict[str, Any]:
        """The options as ``make`` keyword arguments (for configs and reports)."""
        return {
            "obs_noise": None if self.noise is None else self.noise.tolist(),
            "obs_delay": self.delay,
            "observe": None if self.channels is None else [CHANNELS[c] for c in self.channels],
            "actuator_lag": self.lag,
            "actuator_rate": self.rate,
            "randomize_sensors": self.randomize,
        }

    # -- what the environments derive from it ----------------------------------------------
    def observation_space(self, full: spaces.Box) -> spaces.Box:
        if self.channels is None:
            return full
        idx = list(self.channels)
        return spaces.Box(full.low[idx], full.high[idx], dtype=np.float32)

    def kernel_cfg(self, cfg: np.ndarray) -> np.ndarray:
        """The configuration the kernels run with: with an actuator, incremental (they then
        get zero actions and keep the applied setting written before the call)."""
        if not self.actuating:
            return cfg
        out = cfg.copy()
        out[K.C_INCREMENTAL] = 1.0
        return out

    def actuator_params(self, cfg: np.ndarray) -> np.ndarray:
        """The actuator's parameter vector (``A_*``) for the configuration ``cfg``."""
        act = np.empty(N_ACT_PARAMS)
        act[A_ALPHA] = 1.0 if self.lag == 0.0 else -math.expm1(-cfg[K.C_DT] / self.lag)
        if self.rate is None:
            act[A_RATE_U] = act[A_RATE_NU] = math.inf
        else:
            act[A_RATE_U] = self.rate * (cfg[K.C_U_HI] - cfg[K.C_U_LO])
            act[A_RATE_NU] = self.rate * (cfg[K.C_NU_HI] - cfg[K.C_NU_LO])
        return act


def split_sensor_options(options: Mapping[str, Any] | None, inst: Instruments | None
                         ) -> tuple[dict[str, Any] | None, float, int]:
    """Reset ``options`` without the sensors' keys, and the episode's noise scale and delay
    they give (``NO_SCALE``, ``NO_DELAY``: not given), checked against ``inst``.

    ``obs_noise_scale``: a real >= 0 multiplying the configured noise (refused without
    ``obs_noise``, where it would change nothing); ``obs_delay``: an int from 0 to the
    configured ``obs_delay`` (the delay line's length). ``TypeError`` / ``ValueError``
    naming the option and the value otherwise.
    """
    check_dict("options", options)
    if not options or not any(key in options for key in SENSOR_OPTIONS):
        return (None if options is None else dict(options)), NO_SCALE, NO_DELAY
    rest = dict(options)
    scale, delay = NO_SCALE, NO_DELAY
    if "obs_noise_scale" in rest:
        value = rest.pop("obs_noise_scale")
        scale = check_finite_real("reset option 'obs_noise_scale'", value)
        if scale < 0.0:
            raise ValueError(f"reset option 'obs_noise_scale' must be >= 0, got {value!r}")
        if inst is None or inst.noise is None:
            raise ValueError(f"reset option 'obs_noise_scale' = {value!r} scales the "
                             "observation noise, but this environment was made without "
                             "obs_noise")
    if "obs_delay" in rest:
        most = 0 if inst is None else inst.delay
        delay = check_int(f"reset option 'obs_delay' (at most the configured obs_delay = "
                          f"{most})", rest.pop("obs_delay"), 0, most)
    return rest, scale, delay


def no_actuator() -> np.ndarray:
    """The parameter vector of an actuator that applies the command at once."""
    act = np.empty(N_ACT_PARAMS)
    act[A_ALPHA] = 1.0
    act[A_RATE_U] = act[A_RATE_NU] = math.inf
    return act


# -- actuator kernels -----------------------------------------------------------------------
@kernel
def _follow(applied, command, alpha, rate, lo, hi):
    """The applied setting after one interval: the lag's step towards ``command``, then the
    rate limit, then the range (an exact ``command`` when neither holds it back)."""
    target = command if alpha == 1.0 else applied + alpha * (command - applied)
    if target - applied > rate:
        target = applied + rate
    elif applied - target > rate:
        target = applied - rate
    return lo if target < lo else (hi if target > hi else target)


@kernel
def actuate(ctrl, cmd, cfg, a, act) -> None:
    """One interval of the actuator for one plant.

    ``cmd`` (u0, nu) is the command, moved by the action ``a`` as ``kernels.apply_action``
    moves a setting under ``cfg`` (the env's own configuration, not the kernels'
    incremental one); ``ctrl`` (u0, nu), the applied setting, then follows it with the
    actuator parameters ``act`` (``A_*``).
    """
    K.apply_action(cmd, cfg, a)
    ctrl[0] = _follow(ctrl[0], cmd[0], act[A_ALPHA], act[A_RATE_U], cfg[K.C_U_LO],
                      cfg[K.C_U_HI])
    ctrl[1] = _follow(ctrl[1], cmd[1], act[A_ALPHA], act[A_RATE_NU], cfg[K.C_NU_LO],
                      cfg[K.C_NU_HI])


@kernel
def actuate_batch(ctrl, cmd, cfg, A, act, skip) -> None:
    """``actuate`` for every plant ``i`` of ``ctrl`` (n, 2) and ``cmd`` (n, 2) under its
    action ``A[i]``, except where ``skip[i]`` (a plant the vector kernel resets instead of
    stepping, which ignores its action)."""
    for i in range(ctrl.shape[0]):
        if not skip[i]:
            actuate(ctrl[i], cmd[i], cfg, A[i], act)


# -- per-plant buffers ----------------------------------------------------------------------
class InstrumentBank:
    """The instruments' state for ``n`` plants: commands, delay lines, noise streams, and
    each plant's noise scale and delay in its episode.

    ``low``, ``high``: the full (nine-channel) observation box, where noisy readings clip.
    """

    def __init__(self, inst: Instruments, n: int, low: np.ndarray, high: np.ndarray):
        self.inst = inst
        self.n = n
        self.low = low.astype(np.float64)
        self.high = high.astype(np.float64)
        self.cmd = np.zeros((n, 2))
        self.delay = (np.zeros((n, inst.delay + 1, K.N_OBS), dtype=np.float32)
                      if inst.sensing else None)
        #: each plant's noise scale and delay (intervals) in its episode
        self.scale = np.ones(n)
        self.lag = np.full(n, inst.delay, dtype=np.int64)
        self._note_sensors()
        # a plant has a random stream when it draws normals or its sensors' randomisation
        streamed = inst.noise is not None or inst.randomize
        self.rngs: list[np.random.Generator | None] = [None] * n
        self.parents: list[np.random.Generator | None] = [None] * n
        self.normals = np.zeros((n, NOISE_ROWS, K.N_OBS)) if streamed else None
        self.next_row = np.full(n, NOISE_ROWS, dtype=np.int64)
        self.channels = None if inst.channels is None else np.array(inst.channels)
        self._rows = np.arange(n)

    # -- noise -----------------------------------------------------------------------------
    def seed_noise(self, i: int, parent: np.random.Generator | None) -> None:
        """Give plant ``i`` a noise stream spawned from ``parent`` (its env's generator)
        unless it already has one from that very generator."""
        if self.normals is None or parent is None or parent is self.parents[i]:
            return
        self.rngs[i] = parent.spawn(1)[0]
        self.parents[i] = parent
        self.next_row[i] = NOISE_ROWS  # rows of the old stream are dropped

    def _rng(self, i: int) -> np.random.Generator:
        rng = self.rngs[i]
        if rng is None:  # (set_state before any reset: a stream of its own)
            rng = self.rngs[i] = np.random.default_rng()
        return rng

    def _normals(self, idx: np.ndarray) -> np.ndarray:
        """One observation's normals for each plant of ``idx`` (refilling spent buffers)."""
        normals = self.normals
        assert normals is not None  # (drawn from only by a noisy bank)
        for i in idx[self.next_row[idx] >= NOISE_ROWS].tolist():
            self._rng(i).standard_normal(out=normals[i])
            self.next_row[i] = 0
        z = normals[idx, self.next_row[idx]]
        self.next_row[idx] += 1
        return z

    def measure(self, idx: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """What the sensors read from the exact observations ``obs`` (len(idx), 9)."""
        noise = self.inst.noise
        if noise is None:
            return obs.astype(np.float32)
        # (a scale of 1 multiplies exactly: skipping it changes no bit)
        z = noise * self._normals(idx)
        noisy = obs.astype(np.float64) + (z if self._unit_scale else z * self.scale[idx, None])
        return np.clip(noisy, self.low, self.high).astype(np.float32)

    # -- delay line ------------------------------------------------------------------------
    def begin(self, idx: np.ndarray, scale: np.ndarray | None = None,
              lag: np.ndarray | None = None) -> None:
        """Plants ``idx`` begin episodes: each one's noise scale and delay are drawn
        (``randomize_sensors``) or the defaults (1, the configured delay), then overridden
        by ``scale[j]``, ``lag[j]`` where given (not ``NO_SCALE``, ``NO_DELAY``)."""
        inst = self.inst
        for j, i in enumerate(idx.tolist()):
            s, k = 1.0, inst.delay
            if inst.randomize:
                rng = self._rng(i)
                s = float(rng.random())
                k = int(rng.integers(0, inst.delay + 1))
            if scale is not None and not math.isnan(scale[j]):
                s = float(scale[j])
            if lag is not None and lag[j] != NO_DELAY:
                k = int(lag[j])
            self.scale[i], self.lag[i] = s, k
        self._note_sensors()

    def _note_sensors(self) -> None:
        """Note whether every plant has scale 1, and the delay line's slot every plant
        reads if they share one (-1 otherwise): the fast paths of the common case."""
        self._unit_scale = bool(np.all(self.scale == 1.0))
        first = self.lag[0]
        self._one_slot = int(self.inst.delay - first) if np.all(self.lag == first) else -1

    def start(self, idx: np.ndarray, obs: np.ndarray, scale: np.ndarray | None = None,
              lag: np.ndarray | None = None) -> None:
        """Plants ``idx`` begin an episode at the exact observations ``obs`` (with the noise
        scales and delays ``begin`` sets from ``scale``, ``lag``): the delay line holds
        the first reading throughout (the block was there before)."""
        if self.delay is not None:
            self.begin(idx, scale, lag)
            self.delay[idx] = self.measure(idx, obs)[:, None, :]

    def push(self, idx: np.ndarray, obs: np.ndarray) -> None:
        """Plants ``idx`` took a step to the exact observations ``obs``."""
        if self.delay is None:
            return
        reading = self.measure(idx, obs)
        d = self.delay
        if d.shape[1] > 1:
            d[idx, :-1] = d[idx, 1:]
        d[idx, -1] = reading

    def output(self, idx: np.ndarray | None = None) -> np.ndarray:
        """The observations the agent gets for plants ``idx`` (None: all; a copy): the
        reading ``lag[i]`` intervals old, slot ``obs_delay - lag[i]`` of the line."""
        assert self.delay is not None  # (read only from a sensing bank)
        if self._one_slot >= 0:
            out = self.delay[slice(None) if idx is None else idx, self._one_slot]
            if idx is None and self.channels is None:
                out = out.copy()
        else:
            rows = self._rows if idx is None else idx
            out = self.delay[rows, self.inst.delay - self.lag[rows]]
        return out[..., self.channels] if self.channels is not None else out

    # -- state -----------------------------------------------------------------------------
    def noise_state(self, i: int) -> tuple[Mapping[str, Any] | None, np.ndarray] | None:
        """Plant ``i``'s noise stream: its generator's state and its unread normals."""
        if self.normals is None:
            return None
        rng = self.rngs[i]
        rows = self.normals[i, self.next_row[i]:].copy()
        return (None if rng is None else rng.bit_generator.state, rows)

    def restore_sensors(self, i: int, scale: float, lag: int | None) -> None:
        """Plant ``i``'s noise scale and delay as a ``PlantState`` holds them (None: the
        configured delay)."""
        self.scale[i] = scale
        self.lag[i] = self.inst.delay if lag is None else lag
        self._note_sensors()

    def set_noise_state(self, i: int,
                        noise: tuple[Mapping[str, Any] | None, np.ndarray] | None) -> None:
        if self.normals is None:
            return
        assert noise is not None  # check_state refuses a state without one for a noisy bank
        gen_state, rows = noise
        if gen_state is None:
            self.rngs[i] = None
        else:
            bitgen = getattr(np.random, gen_state["bit_generator"])()
            bitgen.state = gen_state
            self.rngs[i] = np.random.Generator(bitgen)
        m = rows.shape[0]
        self.normals[i, NOISE_ROWS - m:] = rows
        self.next_row[i] = NOISE_ROWS - m


def check_noise_state(noise: Any, where: str) -> None:
    """``ValueError`` / ``TypeError`` naming ``where`` unless ``noise`` is what
    ``InstrumentBank.noise_state`` returns."""
    if not (isinstance(noise, tuple) and len(noise) == 2):
        raise TypeError(f"{where} must be (generator state, unread normals), {got(noise)}")
    gen_state, rows = noise
    if gen_state is not None and not (isinstance(gen_state, Mapping)
                                      and isinstance(gen_state.get("bit_generator"), str)
                                      and hasattr(np.random, gen_state["bit_generator"])):
        raise TypeError(f"{where}: not a numpy bit generator state, {got(gen_state)}")
    if not (isinstance(rows, np.ndarray) and rows.ndim == 2 and rows.shape[1] == K.N_OBS
            and rows.shape[0] <= NOISE_ROWS and rows.dtype == np.float64):
        raise ValueError(f"{where}: unread normals must be a float64 array (m, {K.N_OBS}) "
                         f"with m <= {NOISE_ROWS}, {got(rows)}")
    if not np.all(np.isfinite(rows)):  # (they are added to readings as they are)
        row, col = (int(i) for i in np.argwhere(~np.isfinite(rows))[0])
        raise ValueError(f"{where}: unread normals hold a non-finite value "
                         f"({float(rows[row, col])!r} at row {row}, column {col})")


@kernel
def actuate_one(ctrl, cmd, cfg, a, act) -> None:
    """``actuate`` for the single environment's plant (one dispatch per step)."""
    actuate(ctrl, cmd, cfg, a, act)
