"""Warm-starting PPO from the exact-model MPC (DAgger through the plant-state API)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from fricenv_agents import train as T
from fricenv_agents.config import split_hyperparams
from fricenv_agents.imitation import WarmStart, _discounted

SHORT = ["--algo", "ppo", "--scene", "self_excited", "--seed", "2", "-n", "64",
         "--no-progress", "--eval-freq", "0", "--eval-episodes", "2", "--quiet"]


def test_warm_start_settings_are_checked_naming_the_bad_value():
    assert WarmStart.from_mapping({"rounds": 2}).rounds == 2
    for bad, needle in (({"rounds": 0}, "warm_start.rounds"),
                        ({"round": 2}, "unknown key(s) ['round']"),
                        ({"learning_rate": -1.0}, "warm_start.learning_rate"),
                        ({"log_std": float("nan")}, "warm_start.log_std"),
                        ({"steps": 0}, "warm_start.steps"),
                        ({"steps": 2.5}, "warm_start.steps"),
                        ([1, 2], "must be a mapping")):
        with pytest.raises(ValueError) as err:
            WarmStart.from_mapping(bad)
        assert needle in str(err.value)


def test_rounds_cover_whole_episodes_unless_steps_are_given():
    assert WarmStart.from_mapping({}).steps is None
    assert WarmStart.from_mapping({"steps": 3}).as_dict()["steps"] == 3


def test_only_ppo_takes_a_warm_start():
    spec = split_hyperparams("ppo", {"warm_start": {"rounds": 3}})
    assert spec.warm_start is not None and spec.warm_start["rounds"] == 3
    with pytest.raises(ValueError, match="on-policy"):
        split_hyperparams("sac", {"warm_start": {"rounds": 3}})


def test_discounted_returns_stop_at_episode_ends():
    rew = np.ones((5, 1))
    done = np.array([[False], [True], [False], [False], [False]])
    out = _discounted(rew, done, 0.5)[:, 0]
    np.testing.assert_allclose(out, [1.5, 1.0, 1.75, 1.5, 1.0])


def test_training_with_a_warm_start_imitates_then_records_it(tmp_path):
    """Two DAgger rounds on 5-step episodes: the imitation loss is recorded per round, the
    policy's exploration noise is the one asked for, and PPO then trains as usual."""
    run = tmp_path / "run"
    ws = "{rounds: 2, epochs: 2, log_std: -2.0, value_epochs: 1}"
    T.main([*SHORT, "--run-dir", str(run), "-params", f"warm_start:{ws}", "n_steps:32",
            "batch_size:32", "env_kwargs:{max_episode_steps: 5}", "n_envs:2"])
    cfg = yaml.safe_load((run / "config.yml").read_text())
    ws_done = cfg["warm_start"]
    assert ws_done["rounds"] == 2 and len(ws_done["imitation_loss"]) == 2
    assert all(np.isfinite(ws_done["imitation_loss"])) and ws_done["env_steps"] == 2 * 5 * 2
    assert cfg["timesteps_done"] >= 64
    from stable_baselines3 import PPO

    model = PPO.load(run / "model.zip", device="cpu")
    # PPO's few updates move log_std only a little from the warm start's value
    assert float(model.policy.log_std.detach().mean()) == pytest.approx(-2.0, abs=0.1)


def test_rounds_of_fewer_steps_label_only_the_episodes_starts(tmp_path):
    """``steps`` shorter than the training episodes: each round labels that many intervals
    per plant (2 rounds x 3 steps x 2 plants), and more steps than an episode has are
    refused before any label is made."""
    run = tmp_path / "run"
    ws = "{rounds: 2, steps: 3, epochs: 1, value_epochs: 1}"
    T.main([*SHORT, "--run-dir", str(run), "-params", f"warm_start:{ws}", "n_steps:32",
            "batch_size:32", "env_kwargs:{max_episode_steps: 5}", "n_envs:2"])
    ws_done = yaml.safe_load((run / "config.yml").read_text())["warm_start"]
    assert ws_done["steps"] == 3 and ws_done["env_steps"] == 2 * 3 * 2
    assert len(ws_done["imitation_loss"]) == 2

    from fricenv_agents.envs import make_sb3_env
    from fricenv_agents.imitation import dagger
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    env = VecNormalize(make_sb3_env("self_excited", 2, 0, {"max_episode_steps": 5}))
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=32, device="cpu")
    with pytest.raises(ValueError, match=r"warm_start.steps \(6\) exceeds"):
        dagger(model, env, "self_excited", {"max_episode_steps": 5},
               WarmStart(rounds=1, steps=6), seed=0)
