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

Defaults (horizon 12 intervals = one natural period, 256 samples, two iterations) come
from the sweep of return against compute in ``scripts/mpc_sweep.py``
(``docs/results/mpc_sweep.md``): shorter horizons lose the forced paper scene, longer
ones need more samples than they are worth; fewer samples lose return in every scene; at
the same compute a second iteration beats twice the samples.

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

DEFAULT_HORIZON = 12
DEFAULT_SAMPLES = 256
#: A second iteration gained more return than twice the samples at the same compute, in
#: every scene of the sweep (docs/results/mpc_sweep.md).
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
#: First plant seed of the episodes the settings were tuned on: after the best-constant
#: search's block, below no evaluation seed (``fricenv_agents.layout``'s seed layout).
TUNE_SEED_BASE = SEARCH_SEED_BASE + MAX_PLANTS


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
    (``max_episode_steps`` is ignored). ``seed`` seeds the perturbations. With
    ``exact_state=False`` it ignores ``bind`` and always plans from the observation (the
    benchmark's MPC under sensor noise).
    """

    label = "MPC (MPPI, exact model)"

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None, *,
                 horizon: int = DEFAULT_HORIZON, samples: int = DEFAULT_SAMPLES,
                 iterations: int = DEFAULT_ITERATIONS, noise_std: float = DEFAULT_NOISE_STD,
                 temperature: float = DEFAULT_TEMPERATURE, seed: int | None = 0,
                 parallel: bool = True, exact_state: bool = True):
        kwargs = dict(env_kwargs or {})
        kwargs.pop("max_episode_steps", None)
        self.setup = EnvSetup.build(scene, **kwargs)
        self.scene = self.setup.scene
        self.action_space = self.setup.action_space
        self.horizon = check_int("horizon", horizon, 1)
        self.samples = check_int("samples", samples, 2)
        self.iterations = check_int("iterations", iterations, 1)
        self.noise_std = check_finite_real("noise_std", noise_std)
        self.temperature = check_finite_real("temperature", temperature)
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
