"""rl-baselines3-zoo trains on the project's hyperparameter files as they are.

rl_zoo3 is no dependency of fricenv (docs/agents.md shows its command), so this test runs
only where it is installed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rl_zoo3")

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "fricenv/StickSlipSelfExcited-v0"


def test_rl_zoo3_trains_from_the_project_yml(tmp_path):
    from stable_baselines3 import PPO

    res = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", ENV_ID,
         "--gym-packages", "fricenv", "--conf-file", "agents/hyperparams/ppo.yml",
         "-n", "256", "--eval-freq", "-1", "--seed", "0", "-f", str(tmp_path),
         "--hyperparams", "n_envs:2", "n_steps:64", "batch_size:64", "n_epochs:1"],
        cwd=ROOT, env={**os.environ, "MPLBACKEND": "Agg"}, capture_output=True, text=True,
        timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    [run] = (tmp_path / "ppo").iterdir()
    name = ENV_ID.replace("/", "-")
    model = PPO.load(run / f"{name}.zip", device="cpu")
    assert model.num_timesteps == 256
    # the yml's policy_kwargs string, as the zoo parses it
    assert model.policy.net_arch in ([64, 64], {"pi": [64, 64], "vf": [64, 64]})
    assert (run / name / "vecnormalize.pkl").exists()  # normalize: from the yml
