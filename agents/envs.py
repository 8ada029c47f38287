"""The training environment: the native SB3 vector env, monitored and seeded."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def make_sb3_env(scene: str, n_envs: int, seed: int, env_kwargs: dict | None = None,
                 monitor_file: str | Path | None = None) -> Any:
    """The native SB3 vector env (one numba call per step), monitored, seeded ``seed + i``."""
    from stable_baselines3.common.vec_env import VecMonitor

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    venv = StickSlipSB3VecEnv(num_envs=n_envs, scene=scene, **(env_kwargs or {}))
    venv.seed(seed)
    return VecMonitor(venv, filename=None if monitor_file is None else str(monitor_file),
                      info_keywords=("episode_stick_fraction",))
