"""Model-predictive control on the exact plant: MPPI over the batch rollout.

At every control instant, for every plant, MPPI (model-predictive path integral control,
Williams et al. 2017) perturbs its current plan, a sequence of ``horizon`` normalised
actions, with Gaussian noise into ``samples`` sequences, rolls them all out on the exact
plant model (``fricenv.envs.rollout``: the environment's own kernels, every plant and
sample in one numba call), and replaces the plan by the samples' average weighted by
``exp(return / (temperature * spread))``, ``iterations`` times. It applies the plan's
first action and shifts the plan by one interval as the next instant's starting guess.
The plan itself is one of the samples, so a step never scores below keeping it.

The model is the plant: the same reward (stick, velocity fluctuation, effort), the same
action mode and ranges, the actuator if the env has one. What the controller needs is
the plant's state:

- bound to an environment (``bind(env)``, which ``fricenv_agents.rollouts.rollout`` does for any
  controller that has it), it reads the exact state of every plant, the episode's
  randomised parameters included (``state_arrays()`` / ``get_state()``): the
  "exact-model MPC" of the benchmark. This is the only way it works under partial
  observation (``observe=...``): the observation alone does not determine the state.
- unbound, it estimates the state from the observation (``fricenv.envs.observation.
  plants_from_observations``) with the scene's nominal parameters: under observation
  noise it plans from the noisy state as if it were exact, and under a delay from the
  delayed one (no filter, no predictor).

Defaults: per scene, the settings the search of ``fricenv_agents.mpc_tuning`` picked on
tuning episodes disjoint from every evaluation episode (``TUNED``;
``docs/results/mpc_tuning.md`` has its table and the compute of each setting). A scene it
did not tune (a custom ``Scene``) gets the generic ``DEFAULT_*`` values, the earlier
defaults from the one-at-a-time sweep of ``scripts/mpc_sweep.py``
(``docs/results/mpc_sweep.md``). Any setting passed explicitly wins over both.

An observation no environment of the controller's settings can give (NaN, a value outside
the observation box, a stick flag other than 0 or 1, an empty batch) is refused with a
``ValueError`` naming it, bound or not: a plan made from it would be silently wrong.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fricenv.checks import check_bool, check_finite_real, check_int, got
from fricenv.envs.observation import check_observations, plants_from_observations
from fricenv.envs.rollout import BatchRollout
from fricenv.envs.scenes import Scene
from fricenv.envs.setup import EnvSetup

from .layout import MAX_PLANTS, SEARCH_SEED_BASE

#: The generic settings (a scene without tuned ones): horizon 12 intervals is one natural
#: period.
DEFAULT_HORIZON = 12
DEFAULT_SAMPLES = 256
DEFAULT_ITERATIONS = 2
#: Standard deviation of the perturbations, in normalised action units (range [-1, 1]).
DEFAULT_NOISE_STD = 0.5
#: Weights exp(z / temperature) with z the return's distance to the best in units of the
#: returns' standard deviation: small values average only the best few samples.
DEFAULT_TEMPERATURE = 0.1
#: Each later iteration's perturbations are this fraction of the previous ones.
NOISE_DECAY = 0.5
#: The MPPI settings a scene's defaults fix, in the order tables list them.
SETTINGS = ("horizon", "samples", "iterations", "temperature", "noise_std")
#: Each scene's settings, picked by ``fricenv_agents.mpc_tuning`` (the highest mean return
#: on 4 tuning episodes over iterations x temperature x samples, then the horizon around
#: the best; docs/results/mpc_tuning.md). Four iterations won on every scene, temperature
#: 0.03 on three of four, 512 samples on paper and stribeck, a horizon of 8 on viscous and
#: stribeck.
TUNED: dict[str, dict[str, Any]] = {
    "self_excited": {"horizon": 12, "samples": 256, "iterations": 4, "temperature": 0.03,
                     "noise_std": 0.5},
    "paper": {"horizon": 12, "samples": 512, "iterations": 4, "temperature": 0.03,
              "noise_std": 0.5},
    "viscous": {"horizon": 8, "samples": 256, "iterations": 4, "temperature": 0.03,
                "noise_std": 0.5},
    "stribeck": {"horizon": 8, "samples": 512, "iterations": 4, "temperature": 0.1,
                 "noise_std": 0.5},
}
#: First plant seed of the episodes the settings were tuned on: after the best-constant
#: search's block, below no evaluation seed (``fricenv_agents.layout``'s seed layout).
TUNE_SEED_BASE = SEARCH_SEED_BASE + MAX_PLANTS


def scene_settings(scene: str | Scene, **given: Any) -> dict[str, Any]:
    """The MPPI settings for ``scene``: those passed in ``given`` (``None`` meaning not
    passed), else the scene's tuned ones (``TUNED``), else the generic ``DEFAULT_*``.
    ``ValueError`` naming an unknown setting."""
    unknown = set(given) - set(SETTINGS)
    if unknown:
        raise ValueError(f"unknown MPPI settings {sorted(unknown)}; expected {list(SETTINGS)}")
    name = scene if isinstance(scene, str) else getattr(scene, "name", "")
    generic = {"horizon": DEFAULT_HORIZON, "samples": DEFAULT_SAMPLES,
               "iterations": DEFAULT_ITERATIONS, "temperature": DEFAULT_TEMPERATURE,
               "noise_std": DEFAULT_NOISE_STD}
    base = {**generic, **TUNED.get(name, {})}
    return {k: base[k] if given.get(k) is None else given[k] for k in SETTINGS}


def observation_batch(observation: Any, setup: EnvSetup) -> tuple[np.ndarray, np.ndarray]:
    """``observation`` as float32 and as a batch ``(n, m)`` (one row for a single
    observation ``(m,)``). ``ValueError`` naming the row, channel and value for anything
    an environment of ``setup`` cannot give (``fricenv.envs.observation.
    check_observations``: an empty batch, the wrong shape, NaN or inf, a value outside the
    observation box, a stick flag other than 0 or 1), so that no plan is made from it."""
    obs = np.asarray(observation, dtype=np.float32)
    if obs.ndim not in (1, 2):
        raise ValueError(f"observation must have shape (m,) or (n, m), got {obs.shape}")
    batch = obs.reshape(1, -1) if obs.ndim == 1 else obs
    check_observations(batch, setup)
    return obs, batch


class MPPIController:
    """MPPI on the exact plant (see the module docstring), with SB3's ``predict``.

    ``scene`` and ``env_kwargs`` make the model, as they make the environment it controls
    (``max_episode_steps`` is ignored). The MPPI settings left ``None`` are the scene's
    (``scene_settings``). ``seed`` seeds the perturbations. With
    ``exact_state=False`` it ignores ``bind`` and always plans from the observation (the
    benchmark's MPC under sensor noise).
    """

    label = "MPC (MPPI, exact model)"

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None, *,
                 horizon: int | None = None, samples: int | None = None,
                 iterations: int | None = None, noise_std: float | None = None,
                 temperature: float | None = None, seed: int | None = 0,
                 parallel: bool = True, exact_state: bool = True):
        kwargs = dict(env_kwargs or {})
        kwargs.pop("max_episode_steps", None)
        self.setup = EnvSetup.build(scene, **kwargs)
        self.scene = self.setup.scene
        self.action_space = self.setup.action_space
        c = scene_settings(self.scene, horizon=horizon, samples=samples,
                           iterations=iterations, noise_std=noise_std,
                           temperature=temperature)
        self.horizon = check_int("horizon", c["horizon"], 1)
        self.samples = check_int("samples", c["samples"], 2)
        self.iterations = check_int("iterations", c["iterations"], 1)
        self.noise_std = check_finite_real("noise_std", c["noise_std"])
        self.temperature = check_finite_real("temperature", c["temperature"])
        if self.noise_std <= 0.0 or self.temperature <= 0.0:
            raise ValueError(f"noise_std and temperature must be > 0, got {noise_std!r} and "
                             f"{temperature!r}")
        self.parallel = check_bool("parallel", parallel)
        self.exact_state = check_bool("exact_state", exact_state)
        if not self.exact_state:
            self.label = "MPC (MPPI, state from the observation)"
        self.rng = np.random.default_rng(seed)
        self.n_act = self.action_space.shape[0]
        self._env: Any = None
        self._n = 0
        self._plan = np.zeros((0, self.horizon, self.n_act))
        self._roll: BatchRollout | None = None
        inst = self.setup.instruments
        self._partial = inst is not None and inst.channels is not None
        self._nominal = self.scene.params.to_array()

    def describe(self) -> dict[str, Any]:
        return {"label": self.label, "class": type(self).__name__, "horizon": self.horizon,
                "samples": self.samples, "iterations": self.iterations,
                "noise_std": self.noise_std, "temperature": self.temperature,
                "state": "exact (bound)" if self._env is not None else "from observation"}

    # -- state -------------------------------------------------------------------------------
    def bind(self, env: Any) -> None:
        """Plan from ``env``'s exact plant states from now on (a vector env, or a single env
        wrapped or not); ``None`` unbinds."""
        if env is not None and not (hasattr(env, "state_arrays")
                                    or hasattr(getattr(env, "unwrapped", None), "get_state")):
            raise TypeError(f"env must be a fricenv environment, {got(env)}")
        self._env = env if self.exact_state else None

    def _states(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        env = self._env
        if env is None:
            if self._partial:
                raise ValueError("the MPC needs the plant's state: under partial observation "
                                 "bind it to the environment (bind(env)) to plan from the "
                                 "exact state")
            return plants_from_observations(obs, self._nominal, self.scene.tone_gains)
        if hasattr(env, "state_arrays"):
            plants, cmds = env.state_arrays()
        else:
            state = env.unwrapped.get_state()
            plants, cmds = state.plant[None], state.command[None]
        if plants.shape[0] != obs.shape[0]:
            raise ValueError(f"{obs.shape[0]} observations for the {plants.shape[0]} plants "
                             "of the bound environment")
        return plants, cmds

    def _size(self, n: int) -> None:
        """Buffers for ``n`` plants (made again only when ``n`` changes)."""
        if n == self._n:
            return
        self._n = n
        self._plan = np.zeros((n, self.horizon, self.n_act))
        self._roll = BatchRollout(self.setup, n * self.samples, self.horizon, self.parallel)
        self._sources = np.repeat(np.arange(n), self.samples)

    # -- control ----------------------------------------------------------------------------
    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        obs, batch = observation_batch(observation, self.setup)
        self._size(batch.shape[0])
        if episode_start is not None:
            self._plan[np.asarray(episode_start, dtype=bool).reshape(-1)] = 0.0
        plants, cmds = self._states(batch)
        act = self.plan(plants, cmds).astype(np.float32)
        return (act if obs.ndim == 2 else act[0]), state

    def plan(self, plants: np.ndarray, cmds: np.ndarray,
             sources: np.ndarray | None = None) -> np.ndarray:
        """One MPPI decision for every plant; returns the first actions (n, n_act) and keeps
        the shifted plans for the next call.

        The samples start from rows of ``plants``, ``cmds``: by default row i for every
        sample of plant i; ``sources`` (n * samples,) names each sample's start row instead
        (plant i's samples are ``sources[i * samples:(i + 1) * samples]``), so that samples
        can start from different draws of a state estimate (``fricenv_agents.estimation``).
        """
        n, k, h, a = self._n, self.samples, self.horizon, self.n_act
        src = self._sources if sources is None else sources
        sigma = self.noise_std
        roll = self._roll
        if roll is None:
            raise RuntimeError("plan() needs the buffers that a first predict() makes")
        for _ in range(self.iterations):
            eps = self.rng.standard_normal((n, k, h, a)) * sigma
            eps[:, 0] = 0.0  # the current plan is a sample
            cand = np.clip(self._plan[:, None] + eps, -1.0, 1.0)
            res = roll.run((plants, cmds), cand.reshape(n * k, h, a), src)
            ret = res.rewards.sum(axis=1).reshape(n, k)
            ret = np.where(res.status.reshape(n, k) > 0, -np.inf, ret)
            if not np.all(np.isfinite(ret.max(axis=1))):
                raise RuntimeError("every MPC sample of a plant failed to integrate")
            spread = np.nanstd(np.where(np.isfinite(ret), ret, np.nan), axis=1, keepdims=True)
            z = (ret - ret.max(axis=1, keepdims=True)) / (self.temperature * spread + 1e-12)
            w = np.exp(z)
            w /= w.sum(axis=1, keepdims=True)
            self._plan = np.einsum("nk,nkha->nha", w, cand)
            sigma *= NOISE_DECAY
        first = self._plan[:, 0].copy()
        self._plan[:, :-1] = self._plan[:, 1:]  # warm start: the rest of the plan, held
        return first
