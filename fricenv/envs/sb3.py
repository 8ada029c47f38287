"""Stable-Baselines3 ``VecEnv`` adapter over the native vector environment.

SB3 expects same-step autoreset, ``dones`` and a list of per-env info dicts carrying
``terminal_observation`` and ``TimeLimit.truncated`` (so PPO bootstraps truncated episodes).
This adapter provides exactly that on top of ``StickSlipVectorEnv`` in same-step mode, so
PPO trains on N plants stepped by one numba call, without ``DummyVecEnv``'s per-env loop.
"""

from __future__ import annotations

from collections.abc import Sequence
from copy import deepcopy
from typing import Any, Unpack

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from fricenv.envs.settings import EnvKwargs, EnvSettings, settings_signature
from fricenv.envs.vector import StickSlipVectorEnv

#: The per-interval values each plant's info holds, as the vector env reports them.
_INFO_KEYS = ("stick_fraction", "effort", "velocity_variance", "mean_relative_velocity")


def _step_values(info: dict[str, Any], key: str) -> np.ndarray:
    """Every plant's ``key`` of the step the vector env's same-step ``info`` reports: a
    plant whose episode ended and restarted on it has its value in ``final_info``."""
    final = info.get("final_info")
    if final is None:
        return info[key]
    if key not in info:  # every plant restarted
        return final[key]
    return np.where(info["_" + key], info[key], final[key])


class StickSlipSB3VecEnv(VecEnv):
    """SB3 view of ``num_envs`` plants: ``StickSlipSB3VecEnv(num_envs=64, scene="paper")``.

    Arguments are those of ``StickSlipVectorEnv`` (the settings as ``EnvSettings``' fields
    or ``settings=``; ``autoreset_mode`` must be same-step), and it uses only that
    environment's public methods. ``seed()`` and ``set_options()`` act at the next
    ``reset()``, as in SB3: plant i is seeded ``seed + i``, and an option may be a numpy
    array of one value per plant (``set_options({"lam": lams})``). Attribute access
    (``get_attr``, ``set_attr``, ``env_method``) reaches the vector environment, which all
    plants share: ``get_attr`` and ``env_method`` return its one answer for each index
    asked, and ``set_attr`` sets a value for all plants, so it refuses ``indices`` that
    name only some of them. An index outside the plants is an ``IndexError``, as in
    ``DummyVecEnv``.

    The info of a plant whose episode ends also holds ``episode_stick_fraction``, the
    episode's stick-time fraction (``stick_fraction`` is the last interval's), for
    ``VecMonitor(info_keywords=...)`` to log.
    """

    @settings_signature
    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP,
        *,
        settings: EnvSettings | None = None,
        **kwargs: Unpack[EnvKwargs],
    ):
        if autoreset_mode not in (AutoresetMode.SAME_STEP, AutoresetMode.SAME_STEP.value):
            raise ValueError(
                f"SB3 needs same-step autoreset; got autoreset_mode={autoreset_mode!r}")
        self.venv = StickSlipVectorEnv(
            num_envs=num_envs, max_episode_steps=max_episode_steps, render_mode=render_mode,
            autoreset_mode=autoreset_mode,
            settings=EnvSettings.of(settings, kwargs, "StickSlipSB3VecEnv"))
        self._actions: np.ndarray | None = None
        # each plant's running episode: sum of its intervals' stick fractions, and steps
        self._stick_sum = np.zeros(self.venv.num_envs)
        self._episode_steps = np.zeros(self.venv.num_envs, dtype=np.int64)
        super().__init__(
            self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space
        )

    @property
    def settings(self) -> EnvSettings:
        """The settings the plants were made with."""
        return self.venv.settings

    def reset(self) -> np.ndarray:
        obs, _ = self.venv.reset_plants(self._seeds, self._options)  # per-plant seeds, options
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._stick_sum[:] = 0.0
        self._episode_steps[:] = 0
        return obs

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        """Reset options for the next ``reset()``, as SB3's: a list of one dict per plant,
        or one dict for all. A value of one dict for all may be a numpy array of shape
        ``(num_envs,)``, plant i taking element i (``StickSlipVectorEnv.reset_plants``);
        that dict is copied once and shared, not once per plant as SB3 would."""
        if isinstance(options, dict):
            self._options = [deepcopy(options)] * self.num_envs
        else:
            super().set_options(options)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() called before step_async(actions)")
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        # this step's values of every plant, also of those restarted on it
        stick, effort, var, mean_vr = (_step_values(info, key) for key in _INFO_KEYS)
        infos = [
            {"stick_fraction": s, "effort": e, "velocity_variance": q,
             "mean_relative_velocity": m, "TimeLimit.truncated": False}
            for s, e, q, m in zip(stick.tolist(), effort.tolist(), var.tolist(),
                                  mean_vr.tolist(), strict=True)
        ]
        self._stick_sum += stick
        self._episode_steps += 1
        if dones.any():  # ("TimeLimit.truncated" as a DummyVecEnv of gym.make'd envs sets it)
            final_obs = info["final_obs"]
            for i in np.flatnonzero(dones).tolist():
                infos[i]["terminal_observation"] = final_obs[i]
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                infos[i]["episode_stick_fraction"] = float(
                    self._stick_sum[i] / self._episode_steps[i])
            self._stick_sum[dones] = 0.0
            self._episode_steps[dones] = 0
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.venv.render_mode != "rgb_array":
            return [None] * self.num_envs
        frames = self.venv.render()
        return [None] * self.num_envs if frames is None else list(frames)

    def _plants(self, indices: VecEnvIndices) -> list[int]:
        """The plants ``indices`` names (SB3's forms: None, an int or an iterable), each
        checked to be one of them (a negative index counts from the end, as in a list)."""
        plants = []
        for i in self._get_indices(indices):
            if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
                raise TypeError(f"indices must be ints, got {i!r}")
            if not -self.num_envs <= i < self.num_envs:
                raise IndexError(f"index {i} is out of range for {self.num_envs} plants")
            plants.append(int(i) % self.num_envs)
        return plants

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        plants = self._plants(indices)
        value = getattr(self.venv, attr_name)
        return [value for _ in plants]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        if set(self._plants(indices)) != set(range(self.num_envs)):
            raise ValueError(
                f"set_attr({attr_name!r}) with indices={indices!r}: the plants share one "
                "vector environment, so an attribute can only be set for all of them "
                "(indices=None)"
            )
        setattr(self.venv, attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        plants = self._plants(indices)
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in plants]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """True for ``TimeLimit`` only: the plants have its time limit built in (as a
        ``DummyVecEnv`` of ``gym.make``'d envs would report), and no other wrapper."""
        wrapped = wrapper_class is gym.wrappers.TimeLimit
        return [wrapped for _ in self._plants(indices)]
