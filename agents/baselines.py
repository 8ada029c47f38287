"""Baseline controllers: what a user would try before reinforcement learning.

Every baseline has SB3's ``predict(observation, state, episode_start, deterministic)`` and
returns float32 actions in [-1, 1] of the action space's shape (batched if the observation
is), so evaluation treats baselines and trained models alike. Baselines think in physical
settings ``(u0, nu)``; ``ActionMap`` turns a setting into the normalised action of the
environment's action mode (absolute or incremental), which is why they work for every
scene and action mode.

- ``ZeroExcitation``: the excitation off (lowest amplitude); where the action cannot
  reach the amplitude (``action_mode="frequency"``), the scene's starting setting is held,
  i.e. no control.
- ``RandomActions``: uniform actions, seeded.
- ``ConstantExcitation`` / ``search_best_constant``: the best constant open-loop setting.
  The regime map (``fricenv.sweep.regime_map``) gives the steady-state stick fraction on a
  grid over the action range; settings that do not quench stick in steady state cannot win
  and are dropped, and the rest are ranked by the scene's own return on the vector env
  (the reward also charges effort and the transient, which the map does not see).
- ``DitherOnStick``: hand-written feedback; full dither while the block is stuck or its
  velocity is about to reach the belt's, excitation off otherwise.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from fricenv.envs.observation import CHANNELS, actions_towards, setting_ranges
from fricenv.envs.scenes import Scene
from fricenv.envs.setup import EnvSetup
from fricenv.sweep import ALGORITHM as SWEEP_ALGORITHM

from .layout import BASELINES, SEARCH_SEED_BASE
from .rollouts import rollout

#: The channels the baselines read, by position in the full observation.
_STICK, _VR, _U0, _NU = (CHANNELS.index(c) for c in ("stick", "v_rel", "u0", "nu"))
#: Bump when the search changes, so stale caches are recomputed.
SEARCH_VERSION = 1


class ActionMap:
    """Physical settings ``(u0, nu)`` -> normalised actions for one env configuration."""

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None):
        kwargs = dict(env_kwargs or {})
        # the episode length is an argument of the vector env and of gym.make, not of the
        # plant's setup; ``scene`` is the one the env runs, that length included
        horizon = kwargs.pop("max_episode_steps", None)
        setup = EnvSetup.build(scene, **kwargs)
        self.scene = (setup.scene if horizon is None
                      else setup.scene.replace(max_episode_steps=horizon))
        self.setup = setup
        self.action_space = setup.action_space
        self.incremental = setup.incremental
        self.drives_u0 = setup.action_mode != "frequency"
        self.drives_nu = setup.action_mode != "amplitude"
        ranges = setting_ranges(setup)
        self.u_range, self.nu_range = ranges["u0"], ranges["nu"]

    def action(self, u0: Any, nu: Any, obs: np.ndarray) -> np.ndarray:
        """Actions (n, n_act) reaching ``(u0, nu)`` from observations ``obs`` (n, 9)
        (``fricenv.envs.observation.actions_towards`` from the observed setting)."""
        return actions_towards(self.setup, (u0, nu), (obs[:, _U0], obs[:, _NU]))


class Baseline:
    """Common ``predict``; subclasses implement ``_act(obs) -> (n, n_act)``."""

    label = "baseline"

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None):
        self.map = ActionMap(scene, env_kwargs)
        self.scene = self.map.scene
        self.action_space = self.map.action_space

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        obs = np.asarray(observation, dtype=np.float32)
        m = len(CHANNELS)
        if obs.shape[-1] != m or obs.ndim not in (1, 2):
            raise ValueError(f"observation must have shape ({m},) or (n, {m}), "
                             f"got {obs.shape}")
        act = np.clip(self._act(obs.reshape(-1, m)), -1.0, 1.0).astype(np.float32)
        return (act if obs.ndim == 2 else act[0]), state

    def _act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        return {"label": self.label, "class": type(self).__name__}


class ZeroExcitation(Baseline):
    """Excitation off: the plant as it is, the reference every controller must beat."""

    label = "zero excitation"

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None):
        super().__init__(scene, env_kwargs)
        if not self.map.drives_u0:  # the amplitude is the scene's: hold its setting
            p = self.scene.params
            self.label = f"no control (u0 = {p.u0:g}, nu = {p.nu:g} held)"

    def _act(self, obs: np.ndarray) -> np.ndarray:
        return self.map.action(self.map.u_range[0], self.scene.params.nu, obs)


class RandomActions(Baseline):
    """Uniform random actions: what an untrained policy does (seeded, reproducible)."""

    label = "random actions"

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None,
                 seed: int | None = 0):
        super().__init__(scene, env_kwargs)
        self.rng = np.random.default_rng(seed)

    def _act(self, obs: np.ndarray) -> np.ndarray:
        shape = (obs.shape[0], *self.action_space.shape)
        return self.rng.uniform(-1.0, 1.0, shape).astype(np.float32)


class ConstantExcitation(Baseline):
    """Open loop: one setting ``(u0, nu)`` for the whole episode, one per plant if arrays."""

    label = "constant"

    def __init__(self, u0: Any, nu: Any, scene: str | Scene = "self_excited",
                 env_kwargs: dict | None = None, label: str | None = None):
        super().__init__(scene, env_kwargs)
        self.u0 = np.asarray(u0, dtype=float)
        self.nu = np.asarray(nu, dtype=float)
        if label is not None:
            self.label = label

    def _act(self, obs: np.ndarray) -> np.ndarray:
        return self.map.action(self.u0, self.nu, obs)

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "u0": self.u0.tolist(), "nu": self.nu.tolist()}


class DitherOnStick(Baseline):
    """Feedback rule: dither hard when a stick is imminent, stay quiet otherwise.

    Stick needs ``v`` to reach the belt speed; while the block is stuck, or slips with
    ``v - V > -threshold``, the excitation is set to ``on`` (default: the largest amplitude
    at the fastest second tone), else to the zero-excitation setting. Once the free
    oscillation has decayed below the band the rule never fires again, so effort is spent
    only where it prevents sticking. Defaults picked from a handful of settings on the
    search seeds (never the evaluation seeds).
    """

    label = "feedback: dither on imminent stick"

    def __init__(self, scene: str | Scene = "self_excited", env_kwargs: dict | None = None,
                 threshold: float = 0.2, on: tuple[float, float] | None = None):
        super().__init__(scene, env_kwargs)
        self.threshold = float(threshold)
        self.on = on if on is not None else (self.map.u_range[1], self.map.nu_range[1])
        self.off = (self.map.u_range[0], self.scene.params.nu)

    def _act(self, obs: np.ndarray) -> np.ndarray:
        fire = (obs[:, _STICK] > 0.5) | (obs[:, _VR] > -self.threshold)
        u0 = np.where(fire, self.on[0], self.off[0])
        nu = np.where(fire, self.on[1], self.off[1])
        return self.map.action(u0, nu, obs)

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "threshold": self.threshold, "on": list(self.on),
                "off": list(self.off)}


# -- best constant excitation --------------------------------------------------------------
def _stationary_stick_fraction(scene: Scene, u0: np.ndarray, nu: np.ndarray,
                               n_threads: int | None) -> tuple[np.ndarray, Any]:
    """Steady-state stick fraction on the grid (rows u0, columns nu) for the nominal plant."""
    from fricenv.maps import stick_fractions
    from fricenv.sweep import cell_statistics, regime_map

    if scene.tone_gains == (1.0, 1.0):  # regime_map drives both tones with amplitude u0
        rmap = regime_map(scene.params, u0, nu, n_threads=n_threads, progress=False)
        return rmap.stick_fraction, rmap
    g1, g2 = scene.tone_gains
    cells = [scene.params.replace(u0=1.0, u1=g1 * a, u2=g2 * a, nu=b) for a in u0 for b in nu]
    _, st, _, _ = cell_statistics(cells, n_threads=n_threads)
    sf = stick_fractions(st).reshape(u0.size, nu.size)
    return sf, None


def search_best_constant(scene: str | Scene = "self_excited", env_kwargs: dict | None = None,
                         *, n_u0: int = 21, n_nu: int = 21, stick_tol: float | None = 0.05,
                         episodes: int = 16, seed: int = SEARCH_SEED_BASE,
                         cache_dir: str | Path | None = None,
                         n_threads: int | None = None) -> dict[str, Any]:
    """Find the best constant ``(u0, nu)`` over the action range; cached as JSON.

    1. Steady-state stick fraction on an ``n_u0 x n_nu`` grid (only the driven dimensions;
       the other stays at the scene's value) with ``fricenv.sweep.regime_map``.
    2. Candidates: cells within ``stick_tol`` of the grid's lowest stick fraction (``None``:
       every cell) plus the zero-excitation cell.
    3. Each candidate runs the same ``episodes`` episodes (seeds ``seed + j``, disjoint from
       training and evaluation seeds) in one vector env; the best mean return wins.

    With ``cache_dir`` the result is stored in ``best_constant_<scene>.json`` and reused
    when the same search is asked for again.
    """
    env_kwargs = dict(env_kwargs or {})
    amap = ActionMap(scene, env_kwargs)
    sc = amap.scene
    u0 = (np.linspace(*amap.u_range, n_u0) if amap.drives_u0
          else np.array([sc.params.u0]))
    nu = (np.linspace(*amap.nu_range, n_nu) if amap.drives_nu
          else np.array([sc.params.nu]))
    key = {
        # the sweep's measurement version too: a cache made by other physics code is stale
        "version": SEARCH_VERSION, "sweep_algorithm": SWEEP_ALGORITHM,
        "scene": sc.name, "env_kwargs": env_kwargs,
        "u0": u0.tolist(), "nu": nu.tolist(), "stick_tol": stick_tol, "episodes": episodes,
        "seed": seed, "reward_weights": list(sc.reward_weights), "control_dt": sc.control_dt,
        "max_episode_steps": sc.max_episode_steps,
    }
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
    cache = None
    if cache_dir is not None:
        cache = Path(cache_dir) / f"best_constant_{sc.name}.json"
        if cache.exists():
            old = json.loads(cache.read_text())
            if old.get("digest") == digest:
                return old

    t0 = time.perf_counter()
    sf, rmap = _stationary_stick_fraction(sc, u0, nu, n_threads)
    t_map = time.perf_counter() - t0
    finite = np.where(np.isfinite(sf), sf, np.inf)
    if stick_tol is None:
        keep = np.ones(sf.shape, dtype=bool)
    else:
        keep = finite <= finite.min() + stick_tol
    keep[0, :] |= amap.drives_u0 and u0[0] == amap.u_range[0]  # zero excitation: reference
    iu, jn = np.nonzero(keep)
    cu, cn = u0[iu], nu[jn]

    t1 = time.perf_counter()
    n_c = cu.size
    ctrl = ConstantExcitation(np.repeat(cu, episodes), np.repeat(cn, episodes), sc, env_kwargs)
    seeds = [seed + j for _ in range(n_c) for j in range(episodes)]
    m = rollout(ctrl, sc, seeds, n_c * episodes, env_kwargs)
    t_env = time.perf_counter() - t1
    ret = m.ret.reshape(n_c, episodes)
    stick = m.stick_fraction.reshape(n_c, episodes)
    order = np.argsort(-ret.mean(axis=1), kind="stable")
    cands = [{"u0": float(cu[c]), "nu": float(cn[c]),
              "stationary_stick_fraction": float(sf[iu[c], jn[c]]),
              "return_mean": float(ret[c].mean()), "return_std": float(ret[c].std(ddof=1)),
              "stick_fraction_mean": float(stick[c].mean())} for c in order]
    result = {
        "digest": digest, "key": key, "best": cands[0], "candidates": cands,
        "grid_stick_fraction": np.where(np.isfinite(sf), sf, -1.0).tolist(),
        "n_grid_cells": int(sf.size), "n_candidates": int(n_c),
        "seconds_regime_map": round(t_map, 3), "seconds_env": round(t_env, 3),
    }
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_text(json.dumps(result, indent=1))
        if rmap is not None:
            rmap.save(cache.with_name(f"regime_map_{sc.name}.npz"))
    return result


def best_constant(scene: str | Scene = "self_excited", env_kwargs: dict | None = None,
                  **search_kwargs: Any) -> ConstantExcitation:
    """The best constant excitation as a controller (see ``search_best_constant``)."""
    res = search_best_constant(scene, env_kwargs, **search_kwargs)
    b = res["best"]
    label = f"best constant (u0 = {b['u0']:.2f}, nu = {b['nu']:.2f})"
    return ConstantExcitation(b["u0"], b["nu"], scene, env_kwargs, label=label)


def make_baseline(name: str, scene: str | Scene = "self_excited",
                  env_kwargs: dict | None = None, seed: int = 0,
                  search_kwargs: dict | None = None) -> Baseline:
    """A baseline by name (one of ``BASELINES``); ``seed`` seeds the random one."""
    if name == "zero":
        return ZeroExcitation(scene, env_kwargs)
    if name == "random":
        return RandomActions(scene, env_kwargs, seed=seed)
    if name == "best_constant":
        return best_constant(scene, env_kwargs, **(search_kwargs or {}))
    if name == "feedback":
        return DitherOnStick(scene, env_kwargs)
    raise ValueError(f"unknown baseline {name!r}; expected one of {list(BASELINES)}")

