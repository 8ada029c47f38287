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
                        ([1, 2], "must be a mapping")):
        with pytest.raises(ValueError) as err:
            WarmStart.from_mapping(bad)
        assert needle in str(err.value)


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
