"""Controllers and how an episode is scored: the one rollout behind every table.

Training's periodic evaluation, the final evaluation, the baselines' searches and the
benchmark all score episodes with ``rollout``, so the learning curve and the tables
measure the same thing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from fricenv.envs.scenes import Scene


class Controller(Protocol):
    """What a trained model and every baseline offer: SB3's ``predict``."""

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]: ...


class TrainedController:
    """A trained SB3 model plus its observation normalisation, as one ``predict``.

    The model was trained on normalised observations; evaluating it on raw ones would be
    silently wrong, so the statistics travel with it. They are used read-only.
    """

    def __init__(self, model: Any, vecnormalize: Any | None = None, name: str = "agent"):
        self.model = model
        self.vecnormalize = vecnormalize
        self.name = name
        self.action_space = model.action_space

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        obs = np.asarray(observation, dtype=np.float32)
        if self.vecnormalize is not None and self.vecnormalize.norm_obs:
            obs = self.vecnormalize.normalize_obs(obs).astype(np.float32)
        action, state = self.model.predict(obs, state, episode_start, deterministic)
        return np.asarray(action, dtype=np.float32), state


@dataclass
class EpisodeMetrics:
    """Per-episode scores (arrays over episodes)."""

    stick_fraction: np.ndarray
    rms_vr: np.ndarray  #: RMS of v - V over the episode
    rms_vr_fluct: np.ndarray  #: RMS of v - V about its episode mean (vibration)
    effort: np.ndarray
    ret: np.ndarray
    length: np.ndarray

    FIELDS = ("stick_fraction", "rms_vr", "rms_vr_fluct", "effort", "ret", "length")

    @classmethod
    def concat(cls, parts: Iterable[EpisodeMetrics]) -> EpisodeMetrics:
        parts = list(parts)
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in cls.FIELDS))

    def as_dict(self) -> dict[str, list[float]]:
        return {f: getattr(self, f).tolist() for f in self.FIELDS}


def rollout(controller: Controller, scene: str | Scene, seed: int | Sequence[int],
            n_episodes: int,
            env_kwargs: dict | None = None) -> EpisodeMetrics:
    """Run ``n_episodes`` episodes side by side to the horizon.

    Plant j is seeded ``seed + j`` (or ``seed[j]`` for a list), so two controllers run with
    the same seed face the same episodes.

    Metrics are exact integrals over the episode: the kernel reports, per control interval,
    the stuck time and the mean and variance of ``v - V`` (``info``), so ``int (v - V)^2``
    follows without sampling.
    """
    from gymnasium.vector import AutoresetMode

    from fricenv.envs.vector import StickSlipVectorEnv

    # An episode that ends early (its state left the observation box) is restarted by the
    # next step (next-step autoreset) and masked out of the metrics from then on (``alive``),
    # while the others run on to the horizon.
    venv = StickSlipVectorEnv(num_envs=n_episodes, scene=scene,
                              autoreset_mode=AutoresetMode.NEXT_STEP, **(env_kwargs or {}))
    # a model-based controller (fricenv_agents.mpc) reads the plants' exact states while it runs
    bind = getattr(controller, "bind", None)
    try:
        obs, _ = venv.reset(seed=seed if isinstance(seed, int) else [int(s) for s in seed])
        if callable(bind):
            bind(venv)
        alive = np.ones(n_episodes, dtype=bool)
        n = np.zeros(n_episodes)
        ret = np.zeros(n_episodes)
        stick = np.zeros(n_episodes)
        effort = np.zeros(n_episodes)
        vr1 = np.zeros(n_episodes)  # sum over intervals of mean(v - V)
        vr2 = np.zeros(n_episodes)  # sum over intervals of mean((v - V)^2)
        start = np.ones(n_episodes, dtype=bool)
        state = None
        for _ in range(venv.max_episode_steps):
            action, state = controller.predict(obs, state, start, deterministic=True)
            start[:] = False
            obs, r, term, trunc, info = venv.step(np.asarray(action, dtype=np.float32))
            mean_vr = info["mean_relative_velocity"]
            w = alive.astype(float)
            n += w
            ret += w * r
            stick += w * info["stick_fraction"]
            effort += w * info["effort"]
            vr1 += w * mean_vr
            vr2 += w * (info["velocity_variance"] + mean_vr**2)
            alive &= ~(term | trunc)
            if not alive.any():
                break
    finally:
        if callable(bind):
            bind(None)
        venv.close()
    m1 = vr1 / n
    m2 = vr2 / n
    return EpisodeMetrics(stick / n, np.sqrt(m2), np.sqrt(np.maximum(m2 - m1**2, 0.0)),
                          effort / n, ret, n)


def summarize(values: np.ndarray) -> tuple[float, float]:
    """Mean and sample standard deviation (0 for a single value)."""
    values = np.asarray(values, dtype=float)
    std = float(values.std(ddof=1)) if values.size > 1 else 0.0
    return float(values.mean()), std


def fmt_pm(mean: float, std: float, digits: int = 3) -> str:
    """``mean ± std`` for a table cell; ``n/a`` for a mean that is not finite."""
    if not math.isfinite(mean):
        return "n/a"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"
