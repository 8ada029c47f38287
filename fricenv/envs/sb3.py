"""Stable-Baselines3 ``VecEnv`` adapter over the native vector environment.

SB3 expects same-step autoreset, ``dones`` and a list of per-env info dicts carrying
``terminal_observation`` and ``TimeLimit.truncated`` (so PPO bootstraps truncated episodes).
This adapter provides exactly that on top of ``StickSlipVectorEnv`` in same-step mode, so
PPO trains on N plants stepped by one numba call, without ``DummyVecEnv``'s per-env loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from fricenv.envs import kernels as K
from fricenv.envs.vector import StickSlipVectorEnv, plant_seeds


class StickSlipSB3VecEnv(VecEnv):
    """SB3 view of ``num_envs`` plants: ``StickSlipSB3VecEnv(num_envs=64, scene="paper")``.

    Keyword arguments are those of ``StickSlipVectorEnv`` (``autoreset_mode`` is fixed to
    same-step). ``seed()`` and ``set_options()`` act at the next ``reset()``, as in SB3:
    plant i is seeded ``seed + i``. Attribute access (``get_attr``, ``env_method``) reaches
    the vector environment, which all plants share.
    """

    def __init__(self, num_envs: int = 1, **kwargs: Any):
        kwargs["autoreset_mode"] = AutoresetMode.SAME_STEP
        self.venv = StickSlipVectorEnv(num_envs=num_envs, **kwargs)
        self._actions: np.ndarray | None = None
        super().__init__(
            self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space
        )

    def reset(self) -> np.ndarray:
        n = self.num_envs
        seeds = plant_seeds(list(self._seeds), n)  # VecEnv.seed(np.int64(3)) adds numpy ints
        options = [dict(o) if o else {} for o in self._options]
        self.venv._reset_plants(np.arange(n), seeds, options)  # per-plant seeds and options
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(n)]
        return self.venv._obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        res = self.venv._res  # this step's values, also for plants reset just now
        sf = res[K.R_STICK].tolist()
        ef = res[K.R_EFFORT].tolist()
        qv = res[K.R_VAR].tolist()
        mv = res[K.R_MEAN_VR].tolist()
        infos = [
            {"stick_fraction": s, "effort": e, "velocity_variance": q,
             "mean_relative_velocity": m, "TimeLimit.truncated": False}
            for s, e, q, m in zip(sf, ef, qv, mv, strict=True)
        ]
        if dones.any():  # ("TimeLimit.truncated" as a DummyVecEnv of gym.make'd envs sets it)
            final_obs = info["final_obs"]
            for i in np.flatnonzero(dones).tolist():
                infos[i]["terminal_observation"] = final_obs[i]
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.venv.render_mode != "rgb_array":
            return [None] * self.num_envs
        return list(self.venv.render())

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """True for ``TimeLimit`` only: the plants have its time limit built in (as a
        ``DummyVecEnv`` of ``gym.make``'d envs would report), and no other wrapper."""
        wrapped = wrapper_class is gym.wrappers.TimeLimit
        return [wrapped for _ in self._get_indices(indices)]
