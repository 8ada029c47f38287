"""State estimation for the exact-model MPC: a particle filter that knows the sensors' delay.

Under the sensor options of the environments (``fricenv.envs.sensors``) the reading of
step t is the exact observation of the plant ``d = obs_delay`` intervals earlier, plus
Gaussian noise of a standard deviation per channel, clipped to the observation box; the
first reading of an episode fills the delay line, so steps 0 to d repeat it. An MPC that
plans from the reading as if it were the current exact state
(``MPPIController(exact_state=False)``) plans from a state one interval old, with the
scene's nominal plant where the episode drew another.

``ParticleFilter`` keeps, per plant, ``particles`` full plant vectors
(``fricenv.envs.state``: the parameters the episode drew included, sampled from the
scene's randomisation ranges, since the environment draws them there) for the state the
latest reading measured, and the actions given since. At every reading:

1. **propagate** each particle one interval with the action the plant was given then, on
   the environments' own kernels (``BatchRollout`` with horizon 1): the stick-slip
   switching stays exact, and the plant has no process noise, so the model is the plant;
2. **weight** by the reading's likelihood: Gaussian with the environment's standard
   deviation on every noisy channel (``NOISE_FLOOR`` where a continuous channel has none),
   and the stick flag, read without noise, matched up to ``STICK_MISMATCH``; the settings
   are not weighted (every particle applies the same actions);
3. **resample** systematically when the effective sample size falls below
   ``resample_below`` × particles, then **roughen** (Gordon, Salmond and Smith 1993): x, v
   (of slipping particles only: a stuck one keeps v = V exactly), the phases and the
   randomised parameters are jittered by ``roughening`` × the particles' spread ×
   particles^(-1/dims), so that copies of one particle can tell the parameters apart;
4. **predict** the current state: the particles stepped through the d actions given since
   that reading.

The controller (``FilteredMPC``) plans with MPPI from that prediction's mean. A reading no
particle explains (the best misses by more than ``sqrt(REINIT_CHI2)`` standard deviations
per channel, as after an episode restarted without ``episode_start``) starts the plant's
filter again from it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fricenv.checks import check_bool, check_finite_real, check_int, got
from fricenv.envs.observation import (
    CHANNELS,
    RANDOMIZABLE,
    Plants,
    check_observations,
    draw_ranges,
    fresh_workspace,
    observe,
    setting_ranges,
    setting_start,
)
from fricenv.envs.rollout import MAX_SAMPLES, BatchRollout
from fricenv.envs.setup import EnvSetup

from .mpc import (
    MPPIController,
    observation_batch,
)

DEFAULT_PARTICLES = 1000
#: Resample when the effective sample size falls below this fraction of the particles.
DEFAULT_RESAMPLE_BELOW = 0.5
#: Gordon et al.'s constant K of the roughening jitter (0: none).
DEFAULT_ROUGHENING = 0.2
#: Standard deviation the filter assumes on a continuous channel read without noise: the
#: reading is float32 (exact to about 1e-7 of its value), but a likelihood that tight
#: would give one particle all the weight after an interval; a hundredth keeps a few.
NOISE_FLOOR = 1e-2
#: Likelihood of a particle whose stick flag differs from the noise-free reading, relative
#: to one that matches: a hard match that still lets a cloud just across the stick
#: boundary survive (as a 3.7-sigma miss of a Gaussian channel would).
STICK_MISMATCH = 1e-3
#: Mean squared miss per weighted channel, in standard deviations, of the best particle
#: above which a reading starts the plant's filter again (10 sigma on every channel).
REINIT_CHI2 = 100.0
#: Each channel's position in the full observation (``fricenv.envs.channels``).
_CH = {name: i for i, name in enumerate(CHANNELS)}
#: Channels of the likelihood: the state's (the settings carry no information).
_WEIGHED = tuple(_CH[c] for c in ("x", "v_rel", "stick", "cos1", "sin1", "cos2", "sin2"))
_STICK = _CH["stick"]
TWO_PI = 2.0 * math.pi


def _systematic(w: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """``m`` indices drawn from the weights ``w`` (summing to 1) by systematic resampling:
    one uniform, so that each index appears floor or ceil of ``m w`` times."""
    c = np.cumsum(w)
    c[-1] = 1.0
    return np.searchsorted(c, (rng.random() + np.arange(m)) / m).clip(0, w.size - 1)


class ParticleFilter:
    """A particle filter on the exact plant for a batch of plants (module docstring).

    ``setup``: the environment's (``EnvSetup.build(scene, **env_kwargs)``): its sensor
    options are the noise model, its draw bounds the prior. ``particles`` per plant,
    ``resample_below`` in (0, 1], ``roughening`` >= 0, ``seed`` for the filter's draws.
    """

    def __init__(self, setup: EnvSetup, particles: int = DEFAULT_PARTICLES,
                 resample_below: float = DEFAULT_RESAMPLE_BELOW,
                 roughening: float = DEFAULT_ROUGHENING, seed: Any = None,
                 parallel: bool = True):
        self.setup = setup
        self.particles = check_int("particles", particles, 2, MAX_SAMPLES)
        self.resample_below = check_finite_real("resample_below", resample_below)
        if not 0.0 < self.resample_below <= 1.0:
            raise ValueError(f"resample_below must lie in (0, 1], got {resample_below!r}")
        self.roughening = check_finite_real("roughening", roughening)
        if self.roughening < 0.0:
            raise ValueError(f"roughening must be >= 0, got {roughening!r}")
        self.parallel = check_bool("parallel", parallel)
        self.rng = np.random.default_rng(seed)
        inst = setup.instruments
        self.delay = 0 if inst is None else inst.delay
        self.noise = np.zeros(len(CHANNELS)) if inst is None or inst.noise is None else inst.noise
        channels = range(len(CHANNELS)) if inst is None or inst.channels is None else inst.channels
        #: column of each full channel in a reading (-1: not observed)
        self.column = np.full(len(CHANNELS), -1)
        self.column[list(channels)] = np.arange(len(channels))
        self.n_obs = len(channels)
        self.weighed = [c for c in _WEIGHED if self.column[c] >= 0]
        self.n_act = setup.action_space.shape[0]
        sc = setup.scene
        self._base = sc.params.to_array()
        self._gains = sc.tone_gains
        self._ranges = draw_ranges(setup)
        #: the randomised parameters, in the order they are drawn
        self._free = [name for name in RANDOMIZABLE
                      if self._ranges[name][1] > self._ranges[name][0]]
        self._template = fresh_workspace()
        self._n = 0

    # -- buffers ---------------------------------------------------------------------------
    def _size(self, n: int) -> None:
        """Buffers for ``n`` plants (made again only when ``n`` changes; every plant then
        starts at its next reading)."""
        if n == self._n:
            return
        m = n * self.particles
        self._n = n
        self._lag = Plants.new(m).table  # the state the latest reading measured
        self._lag_cmd = np.zeros((m, 2))
        self._now = Plants.new(m).table  # predicted to the current interval
        self._now_cmd = np.zeros((m, 2))
        self._ahead = Plants.new(m).table  # _lag stepped by the oldest action given
        self._ahead_cmd = np.zeros((m, 2))
        self._ahead_ok = np.zeros(n, dtype=bool)
        self._ahead_dead = np.zeros(m, dtype=bool)  # (stepped from a failed interval)
        self.logw = np.full((n, self.particles), -math.log(self.particles))
        self._now_logw = self.logw.copy()
        self._acts = np.zeros((n, self.delay + 1, self.n_act))
        self._n_acts = np.zeros(n, dtype=np.int64)  # actions given since that state
        self._steps = np.zeros(n, dtype=np.int64)  # steps since the episode began
        self._started = np.zeros(n, dtype=bool)
        self._roll = BatchRollout(self.setup, m, 1, self.parallel)
        self._rows = np.arange(m)

    def _block(self, i: int) -> slice:
        return slice(i * self.particles, (i + 1) * self.particles)

    # -- the filter's steps ----------------------------------------------------------------
    def observe(self, reading: np.ndarray, start: np.ndarray | None = None) -> None:
        """Take the readings (n, m) of ``n`` plants; ``start`` (n,) marks plants whose
        episode begins with this reading (all of them at the first call or when ``n``
        changes). Then ``now_states()`` holds the prediction of the current states."""
        obs = np.asarray(reading, dtype=np.float64)
        if obs.ndim != 2 or obs.shape[1] != self.n_obs:
            raise ValueError(f"readings must have shape (n, {self.n_obs}), got {obs.shape}")
        if not np.all(np.isfinite(obs)):
            raise ValueError("readings must be finite (no NaN or inf)")
        check_observations(obs, self.setup)  # (within the box, a 0/1 stick flag: by name)
        n = obs.shape[0]
        self._size(n)
        starting = ~self._started
        if start is not None:
            s = np.asarray(start, dtype=bool).reshape(-1)
            if s.shape != (n,):
                raise ValueError(f"start must have one flag per plant ({n}), got shape "
                                 f"{s.shape}")
            starting |= s
        fresh = ~starting & (self._steps > self.delay)
        lost = np.zeros(n, dtype=bool)
        if fresh.any():
            self._advance(fresh)
            lost = self._update(fresh, obs)
        if (starting | lost).any():
            idx = np.flatnonzero(starting | lost)
            self._init(idx, obs[idx], starting[idx])
            self._started[idx] = True
        self._predict()

    def applied(self, actions: np.ndarray) -> None:
        """Record the actions (n, n_act) the plants are given after the last reading."""
        a = np.asarray(actions, dtype=np.float64).reshape(self._n, self.n_act)
        if np.any(self._n_acts > self.delay):
            raise RuntimeError("applied() twice without a reading in between")
        self._acts[np.arange(self._n), self._n_acts] = a
        self._n_acts += 1
        self._steps += 1

    def _step(self, plants: np.ndarray, cmds: np.ndarray, actions: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every particle one interval on, plant i's under ``actions[i]``: the end plant
        vectors, commands (views of the rollout's buffers) and the failed rows."""
        A = np.repeat(actions, self.particles, axis=0)[:, None, :]
        res = self._roll.run((plants, cmds), A, self._rows)
        ends, end_cmds = self._roll.end_states()
        return ends, end_cmds, res.status > 0

    def _advance(self, plants: np.ndarray) -> None:
        """Step the measured state of ``plants`` (mask) by their oldest action given."""
        todo = plants & ~self._ahead_ok
        if todo.any():
            ends, cmds, failed = self._step(self._lag, self._lag_cmd, self._acts[:, 0])
            self._blocks(ends, cmds, self._ahead, self._ahead_cmd, todo)
            rows = np.repeat(todo, self.particles)
            self._ahead_dead[rows] = failed[rows]
        self._blocks(self._ahead, self._ahead_cmd, self._lag, self._lag_cmd, plants)
        self._kill(self._ahead_dead & np.repeat(plants, self.particles), self.logw, self._lag)
        self._acts[plants, :-1] = self._acts[plants, 1:]
        self._n_acts[plants] -= 1
        self._ahead_ok[plants] = False

    def _kill(self, failed: np.ndarray, logw: np.ndarray, table: np.ndarray) -> None:
        """Particles whose interval failed lose their weight and take a living one's state
        (so that no later step starts from what the failure left)."""
        if not failed.any():
            return
        bad = failed.reshape(self._n, self.particles)
        logw[bad] = -np.inf
        for i in np.flatnonzero(bad.any(axis=1)):
            b = self._block(int(i))
            best = int(np.argmax(logw[i]))
            table[b][bad[i]] = table[b][best]

    def loglik(self, idx: np.ndarray, reading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Log-likelihood (len(idx), P) of the readings of plants ``idx`` given their
        particles' measured states, and each particle's mean squared miss per channel in
        standard deviations (the stick flag's mismatch counted as its log-likelihood)."""
        P = self.particles
        rows = (idx[:, None] * P + np.arange(P)).reshape(-1)
        pred = observe(self._lag[rows], self.setup).reshape(idx.size, P, len(CHANNELS))
        ll = np.zeros((idx.size, P))
        for c in self.weighed:
            miss = reading[:, None, self.column[c]] - pred[:, :, c]
            if c == _STICK and self.noise[c] == 0.0:
                ll += np.where(np.abs(miss) > 0.5, math.log(STICK_MISMATCH), 0.0)
            else:
                ll -= 0.5 * (miss / max(self.noise[c], NOISE_FLOOR)) ** 2
        return ll, -2.0 * ll / max(1, len(self.weighed))

    def _update(self, plants: np.ndarray, reading: np.ndarray) -> np.ndarray:
        """Weight the particles of ``plants`` (mask) by their readings and resample where
        the weights degenerate; returns the mask of plants no particle explains."""
        idx = np.flatnonzero(plants)
        ll, chi2 = self.loglik(idx, reading[idx])
        lost = np.zeros(self._n, dtype=bool)
        logw = self.logw[idx] + ll
        lost[idx] = ~(np.min(np.where(np.isfinite(logw), chi2, np.inf), axis=1) <= REINIT_CHI2)
        with np.errstate(invalid="ignore"):  # (a lost plant's weights: all -inf)
            logw -= logw.max(axis=1, keepdims=True)
            logw -= np.log(np.exp(logw).sum(axis=1, keepdims=True))
        self.logw[idx] = logw
        w = np.exp(logw)
        ess = 1.0 / (w**2).sum(axis=1)
        for j, i in enumerate(idx):
            if not lost[i] and ess[j] < self.resample_below * self.particles:
                self._resample(int(i), w[j])
        return lost

    def _resample(self, i: int, w: np.ndarray) -> None:
        b = self._block(i)
        pick = _systematic(w, self.particles, self.rng)
        self._lag[b] = self._lag[b][pick]
        self._lag_cmd[b] = self._lag_cmd[b][pick]
        self.logw[i] = -math.log(self.particles)
        if self.roughening > 0.0:
            self._roughen(self._lag[b])

    def _roughen(self, T: np.ndarray) -> None:
        """Jitter the particles ``T`` (rows of plant vectors) in place: each coordinate by
        ``roughening`` x its spread x P^(-1/dims), within the prior for the parameters."""
        m = T.shape[0]
        p = Plants(T)
        stuck = p.mode == 0.0
        vr = p.v - p.V
        scale = self.roughening * m ** (-1.0 / (len(self._free) + 4))

        def jitter(values: np.ndarray) -> np.ndarray:
            return scale * np.ptp(values) * self.rng.standard_normal(m)

        dx, dvr = jitter(p.x), jitter(vr)
        dp = [jitter(p.param(name)) for name in self._free]
        for phi in (p.phi1, p.phi2):  # spread of the phases about the first one
            wrapped = (phi - phi[0] + math.pi) % TWO_PI
            phi[:] = (phi + jitter(wrapped)) % TWO_PI
        p.x += dx
        for name, d in zip(self._free, dp, strict=True):
            lo, hi = self._ranges[name]
            p.set_param(name, np.clip(p.param(name) + d, lo, hi))
        V = p.V
        p.v = np.where(stuck, V, V + vr + dvr)
        p.set_param("w2", p.nu * p.param("eta"))
        p.settle_modes()
        p.workspace = self._template

    def _init(self, idx: np.ndarray, reading: np.ndarray, episode: np.ndarray) -> None:
        """Particles of plants ``idx`` from their readings (measured states) and the prior:
        the randomised parameters from their ranges, each observed quantity about its
        reading by the channel's noise, the rest from the episode's starting ranges."""
        P, rng, col = self.particles, self.rng, self.column
        ranges = self._ranges
        m = idx.size * P
        p = Plants.new(m)
        p.params = self._base
        for name in self._free:
            p.set_param(name, rng.uniform(*ranges[name], m))
        start = setting_start(self.setup)
        settings = setting_ranges(self.setup)

        def per_particle(c: int, default: float) -> np.ndarray:
            return np.repeat(reading[:, col[c]] if col[c] >= 0 else
                             np.full(idx.size, default), P)

        def about(c: int, lo_k: Any, hi_k: Any) -> np.ndarray:
            if col[c] < 0:
                return rng.uniform(lo_k, hi_k, m)
            return per_particle(c, 0.0) + max(self.noise[c], NOISE_FLOOR) * rng.standard_normal(m)

        p.u0 = np.clip(per_particle(_CH["u0"], start[0]), *settings["u0"])
        p.nu = np.clip(per_particle(_CH["nu"], start[1]), *settings["nu"])
        p.drive(self._gains)
        p.t = 0.0
        p.x = about(_CH["x"], *ranges["x0"])
        V = p.V
        v0_lo, v0_hi = ranges["v0"]
        p.v = V + about(_CH["v_rel"], v0_lo - V, v0_hi - V)
        if col[_STICK] >= 0 and self.noise[_STICK] == 0.0:
            p.v = np.where(per_particle(_STICK, 0.0) > 0.5, V, p.v)
        for (c, s), phase in (((_CH["cos1"], _CH["sin1"]), "phi1"),
                              ((_CH["cos2"], _CH["sin2"]), "phi2")):
            if col[c] >= 0 and col[s] >= 0:
                sd = max(0.5 * (self.noise[c] + self.noise[s]), NOISE_FLOOR)
                phi = np.arctan2(per_particle(s, 0.0), per_particle(c, 1.0))
                setattr(p, phase, (phi + sd * rng.standard_normal(m)) % TWO_PI)
            else:
                setattr(p, phase, rng.uniform(*ranges[phase], m))
        p.settle_modes()
        p.workspace = self._template
        for j, i in enumerate(idx):
            b = self._block(int(i))
            self._lag[b] = p.table[j * P:(j + 1) * P]
            self._lag_cmd[b] = p.setting[j * P:(j + 1) * P]
            self.logw[i] = -math.log(P)
            self._ahead_ok[i] = False
            if episode[j]:
                self._n_acts[i] = 0
                self._steps[i] = 0

    def _predict(self) -> None:
        """The current states: each plant's particles stepped through the actions given
        since its latest reading (the first such step kept for the next reading)."""
        self._now_logw[:] = self.logw
        self._ahead_ok[:] = False
        self._blocks(self._lag, self._lag_cmd, self._now, self._now_cmd, self._n_acts == 0)
        for j in range(int(self._n_acts.max(initial=0))):
            src = (self._lag, self._lag_cmd) if j == 0 else (self._now, self._now_cmd)
            ends, cmds, failed = self._step(*src, self._acts[:, j])
            moved = self._n_acts > j
            failed &= np.repeat(moved, self.particles)
            if j == 0:
                self._blocks(ends, cmds, self._ahead, self._ahead_cmd, moved)
                self._ahead_dead[:] = failed
                self._ahead_ok[:] = moved
            self._blocks(ends, cmds, self._now, self._now_cmd, moved)
            self._kill(failed, self._now_logw, self._now)

    def _blocks(self, plants: np.ndarray, cmds: np.ndarray, out: np.ndarray,
                out_cmds: np.ndarray, which: np.ndarray) -> None:
        """Copy the particles of the plants ``which`` (mask) into ``out``, ``out_cmds``."""
        if which.all():
            out[:], out_cmds[:] = plants, cmds
            return
        for i in np.flatnonzero(which):
            b = self._block(int(i))
            out[b], out_cmds[b] = plants[b], cmds[b]

    # -- what the controller reads -----------------------------------------------------------
    def now_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The predicted current states: plant vectors (n * P, N_PLANT), commands
        (n * P, 2) and normalised weights (n, P); plant i's particles are rows
        i * P to (i + 1) * P. Buffers of the filter: copy what you keep."""
        w = np.exp(self._now_logw)
        return self._now, self._now_cmd, w / w.sum(axis=1, keepdims=True)

    def draw(self, m: int) -> np.ndarray:
        """``m`` rows of ``now_states()`` per plant (n * m,) drawn from the posterior
        (systematic resampling), plant by plant."""
        _, _, w = self.now_states()
        return np.concatenate([i * self.particles + _systematic(w[i], m, self.rng)
                               for i in range(self._n)])

    def estimate(self) -> dict[str, np.ndarray]:
        """Posterior means (n,) of the current x, v - V and stuck probability, and of each
        randomised parameter."""
        T, _, w = self.now_states()
        P = self.particles
        p = Plants(T)

        def mean(values: np.ndarray) -> np.ndarray:
            return (w * values.reshape(self._n, P)).sum(axis=1)

        out = {"x": mean(p.x), "v_rel": mean(p.v - p.V),
               "stuck": mean((p.mode == 0.0).astype(float))}
        for name in self._free:
            out[name] = mean(p.param(name))
        return out

    def mean_states(self) -> tuple[np.ndarray, np.ndarray]:
        """One plant vector per plant (n, N_PLANT) and its command: the posterior mean of x,
        v, the phases (circular) and the randomised parameters, stuck when most of the
        weight is, on the workspace and settings of its heaviest particle."""
        T, C, w = self.now_states()
        n, P = self._n, self.particles
        heavy = np.arange(n) * P + np.argmax(w, axis=1)
        out, cmds = T[heavy].copy(), C[heavy].copy()
        est = self.estimate()
        each, mean = Plants(T), Plants(out)
        for name in self._free:
            mean.set_param(name, est[name])
        mean.set_param("w2", mean.nu * mean.param("eta"))
        mean.x = est["x"]
        for phase in ("phi1", "phi2"):
            c = (w * np.cos(each.state(phase)).reshape(n, P)).sum(axis=1)
            s = (w * np.sin(each.state(phase)).reshape(n, P)).sum(axis=1)
            setattr(mean, phase, np.arctan2(s, c) % TWO_PI)
        V = mean.V
        slip = (each.mode != 0.0).reshape(n, P)
        vr = (each.v - each.V).reshape(n, P)
        ws = (w * slip).sum(axis=1)
        mean.v = np.where(est["stuck"] > 0.5, V,
                          V + (w * slip * vr).sum(axis=1) / np.maximum(ws, 1e-300))
        mean.settle_modes()
        mean.workspace = self._template
        return out, cmds


#: Where the MPC's samples start: all from the posterior mean (the default), or each from
#: its own draw of the posterior. The mean scored better (docs/control.md): MPPI weighs
#: its samples by their returns' spread, and samples from different starts spread by
#: where they start as well as by their actions.
PLAN_FROM = ("mean", "posterior")


class FilteredMPC(MPPIController):
    """MPPI on the exact plant (``MPPIController``) planning from a particle filter's
    estimate of the current state (``ParticleFilter``), with SB3's ``predict``.

    ``scene`` and ``env_kwargs`` make the model and the filter's noise model
    (``obs_noise``, ``obs_delay``, ``observe``) and prior (``randomize``), as they make
    the environment it controls. The MPPI settings are ``MPPIController``'s (left ``None``:
    the scene's tuned ones, the same as the bound MPC's); ``particles``,
    ``resample_below`` and ``roughening`` are the filter's; ``seed`` seeds both.
    ``plan_from="mean"`` starts every MPPI sample from the posterior mean,
    ``"posterior"`` each from its own draw of the posterior (see ``PLAN_FROM``). It never
    reads the environment's state: ``bind`` is
    ignored, and it works under partial observation too.
    """

    label = "MPC (MPPI, exact model) + particle filter"

    def __init__(self, scene: Any = "self_excited", env_kwargs: dict | None = None, *,
                 horizon: int | None = None, samples: int | None = None,
                 iterations: int | None = None, noise_std: float | None = None,
                 temperature: float | None = None, seed: int | None = 0,
                 parallel: bool = True, particles: int = DEFAULT_PARTICLES,
                 resample_below: float = DEFAULT_RESAMPLE_BELOW,
                 roughening: float = DEFAULT_ROUGHENING, plan_from: str = PLAN_FROM[0]):
        super().__init__(scene, env_kwargs, horizon=horizon, samples=samples,
                         iterations=iterations, noise_std=noise_std, temperature=temperature,
                         seed=seed, parallel=parallel, exact_state=False)
        self.label = type(self).label
        if plan_from not in PLAN_FROM:
            raise ValueError(f"plan_from must be one of {PLAN_FROM}, {got(plan_from)}")
        self.plan_from = plan_from
        filter_seed = None if seed is None else np.random.SeedSequence(seed).spawn(1)[0]
        self.filter = ParticleFilter(self.setup, particles, resample_below, roughening,
                                     filter_seed, parallel)

    def describe(self) -> dict[str, Any]:
        f = self.filter
        return {**super().describe(), "state": "particle filter on the readings",
                "particles": f.particles, "resample_below": f.resample_below,
                "roughening": f.roughening, "plan_from": self.plan_from,
                "obs_delay": f.delay}

    def bind(self, env: Any) -> None:
        """Ignored: the controller estimates the state from the readings alone."""

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        obs, batch = observation_batch(observation, self.setup)
        n = batch.shape[0]
        start = None if episode_start is None else np.asarray(episode_start, bool).reshape(-1)
        if start is not None and start.shape != (n,):
            raise ValueError(f"episode_start must have one flag per plant ({n}), got shape "
                             f"{start.shape}")
        self._size(n)
        if start is not None:
            self._plan[start] = 0.0
        self.filter.observe(batch, start)
        if self.plan_from == "posterior":
            plants, cmds, _ = self.filter.now_states()
            act = self.plan(plants, cmds, self.filter.draw(self.samples))
        else:
            act = self.plan(*self.filter.mean_states())
        act = act.astype(np.float32)
        self.filter.applied(act)  # (float32, as the environment receives it)
        return (act if obs.ndim == 2 else act[0]), state

    def estimate(self) -> dict[str, np.ndarray]:
        """The filter's posterior means of the current states (``ParticleFilter.estimate``)."""
        return self.filter.estimate()


class TrackingProbe:
    """A controller wrapped for scoring its state estimate in ``fricenv_agents.rollouts.
    rollout``: bound to the environment, it reads the plants' exact states after each
    decision and sums the squared errors of x and v - V of the controller's ``estimate()``
    (a ``FilteredMPC``) and of the raw reading, over plants and steps. The controller
    itself never sees the environment."""

    def __init__(self, controller: FilteredMPC):
        if not callable(getattr(controller, "estimate", None)):
            raise TypeError(f"controller must have estimate() (a FilteredMPC), {got(controller)}")
        self.controller = controller
        self.label = controller.label
        self._env: Any = None
        self.sq = {k: 0.0 for k in ("x", "v_rel", "raw_x", "raw_v_rel")}
        self.count = 0

    def bind(self, env: Any) -> None:
        if env is not None and not hasattr(env, "state_arrays"):
            raise TypeError(f"env must be a StickSlipVectorEnv, {got(env)}")
        self._env = env

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        act, state = self.controller.predict(observation, state, episode_start, deterministic)
        if self._env is not None:
            plants = Plants(self._env.state_arrays()[0])
            x, vr = plants.x, plants.v - plants.V
            est = self.controller.estimate()
            obs = np.asarray(observation, dtype=np.float64).reshape(x.size, -1)
            col = self.controller.filter.column
            self.sq["x"] += float(((est["x"] - x) ** 2).sum())
            self.sq["v_rel"] += float(((est["v_rel"] - vr) ** 2).sum())
            cx, cv = col[_CH["x"]], col[_CH["v_rel"]]
            if cx >= 0 and cv >= 0:
                self.sq["raw_x"] += float(((obs[:, cx] - x) ** 2).sum())
                self.sq["raw_v_rel"] += float(((obs[:, cv] - vr) ** 2).sum())
            self.count += x.size
        return act, state

    def rms(self) -> dict[str, float]:
        """Root-mean-square errors over every decision so far: the filter's (x, v_rel) and
        the raw reading's (raw_x, raw_v_rel) against the current exact state."""
        return {k: math.sqrt(v / max(1, self.count)) for k, v in self.sq.items()}


def noise_retention(scene: str, n_seeds: int, episodes: int, env_kwargs: dict,
                    sensors: dict, **settings: Any) -> dict[str, Any]:
    """Stick cut against zero excitation, on the evaluation episodes (seeds k <
    ``n_seeds``, ``episodes`` each, ``env_kwargs`` for every run), of the MPC bound to the
    exact state without sensors (``exact``), and under the sensor options ``sensors`` of
    the MPC planning from the raw reading (``raw``) and of ``FilteredMPC(**settings)``
    (``filtered``); retention is a cut over the exact one. Also the filter's and the raw
    reading's RMS errors of x and v - V against the exact current state (``rms``) and the
    wall time of each run."""
    import time

    from .baselines import ZeroExcitation
    from .layout import eval_env_seed
    from .rollouts import rollout

    check_int("n_seeds", n_seeds, 1)
    check_int("episodes", episodes, 1)
    noisy = {**env_kwargs, **sensors}
    stick: dict[str, list[float]] = {}
    seconds: dict[str, float] = {}
    probes = []
    for k in range(n_seeds):
        probe = TrackingProbe(FilteredMPC(scene, noisy, seed=k, **settings))
        probes.append(probe)
        runs: dict[str, tuple[Any, dict]] = {
            "zero": (ZeroExcitation(scene, env_kwargs), env_kwargs),
            "zero_sensors": (ZeroExcitation(scene, noisy), noisy),
            "exact": (MPPIController(scene, env_kwargs, seed=k), env_kwargs),
            "raw": (MPPIController(scene, noisy, seed=k, exact_state=False), noisy),
            "filtered": (probe, noisy)}
        for key, (ctrl, kw) in runs.items():
            t = time.perf_counter()
            m = rollout(ctrl, scene, eval_env_seed(k), episodes, kw)
            seconds[key] = seconds.get(key, 0.0) + time.perf_counter() - t
            stick.setdefault(key, []).extend(m.stick_fraction.tolist())
    mean = {k: float(np.mean(v)) for k, v in stick.items()}
    cut = {k: 1.0 - mean[k] / mean["zero" if k == "exact" else "zero_sensors"]
           for k in ("exact", "raw", "filtered")}
    count = sum(p.count for p in probes)
    rms = {k: math.sqrt(sum(p.sq[k] for p in probes) / count) for k in probes[0].sq}
    return {"scene": scene, "episodes": n_seeds * episodes, "stick": mean, "cut": cut,
            "retention": {k: cut[k] / cut["exact"] for k in ("raw", "filtered")},
            "rms": rms, "seconds": {k: round(v, 1) for k, v in seconds.items()},
            "per_episode_stick": stick,
            "filter": probes[0].controller.describe()}
