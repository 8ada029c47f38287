"""Agents: training CLI smoke runs, baselines' predict(), evaluation output, CLI errors."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3", reason="the agents need the rl extra")

from fricenv_agents import baselines as B  # noqa: E402
from fricenv_agents import evaluate as E  # noqa: E402
from fricenv_agents import layout as L  # noqa: E402
from fricenv_agents import scoring as S  # noqa: E402
from fricenv_agents import train as T  # noqa: E402
from fricenv_agents.config import (  # noqa: E402
    apply_overrides,
    load_hyperparams,
    split_hyperparams,
)
from fricenv_agents.layout import (  # noqa: E402
    ALGOS,
    MAX_TRAIN_SEED,
    SCENE_ENV_IDS,
    SEED_STRIDE,
    callback_env_seed,
    eval_env_seed,
    train_env_seed,
)
from fricenv_agents.rollouts import rollout  # noqa: E402
from fricenv_agents.runs import load_controller  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(SCENE_ENV_IDS)


def _cli(module: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", module, *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory) -> Path:
    """A few hundred PPO steps through the real command line (a subprocess)."""
    run = tmp_path_factory.mktemp("runs") / "ppo_smoke"
    res = _cli("fricenv_agents.train", "--algo", "ppo", "--scene", "self_excited", "--seed", "3",
               "-n", "256", "--run-dir", str(run), "--no-progress", "--eval-freq", "128",
               "--eval-episodes", "2",
               "-params", "n_envs:4", "n_steps:32", "batch_size:64", "n_epochs:1")
    assert res.returncode == 0, res.stderr
    return run


# -- training ---------------------------------------------------------------------------------
def test_smoke_training_writes_a_loadable_model(ppo_run):
    from stable_baselines3 import PPO

    from fricenv.envs.observation import CHANNELS

    for name in ("config.yml", "model.zip", "vecnormalize.pkl", "evaluations.npz",
                 "eval_log.csv", "monitor.csv"):
        assert (ppo_run / name).exists(), name
    cfg = yaml.safe_load((ppo_run / "config.yml").read_text())
    assert cfg["algo"] == "ppo" and cfg["scene"] == "self_excited" and cfg["seed"] == 3
    assert cfg["timesteps_done"] >= 256 and cfg["train_seconds"] > 0
    assert cfg["train_env_seeds"] == [train_env_seed(3), train_env_seed(3) + 3]
    assert cfg["observation"] == list(CHANNELS)  # (loading compares the names)
    model = PPO.load(ppo_run / "model.zip", device="cpu")
    obs, _ = gym.make(SCENE_ENV_IDS["self_excited"]).reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (2,)
    ctrl, cfg2 = load_controller(ppo_run)  # model + normalisation, as evaluation loads it
    assert cfg2 == cfg and ctrl.vecnormalize is not None
    a, _ = ctrl.predict(np.stack([obs, obs]))
    assert a.shape == (2, 2) and a.dtype == np.float32
    with np.load(ppo_run / "evaluations.npz") as z:
        assert z["timesteps"][0] == 0 and z["timesteps"][-1] == cfg["timesteps_done"]
        assert z["results"].shape == (z["timesteps"].size, 2)


def test_smoke_training_sac_on_the_paper_scene(tmp_path):
    from stable_baselines3 import SAC

    run = tmp_path / "sac"
    res = _cli("fricenv_agents.train", "--algo", "sac", "--scene", "paper", "--seed", "1",
               "-n", "200", "--run-dir", str(run), "--no-progress", "--eval-freq", "0",
               "--eval-episodes", "1", "-params", "n_envs:2", "learning_starts:50",
               "batch_size:32", "buffer_size:1000")
    assert res.returncode == 0, res.stderr
    model = SAC.load(run / "model.zip", device="cpu")
    assert model.action_space.shape == (1,)  # the paper scene retunes nu only


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("scene", SCENES)
def test_every_scene_has_valid_hyperparameters(algo, scene):
    spec = split_hyperparams(algo, load_hyperparams(algo, scene))
    assert spec.n_timesteps >= 1 and spec.n_envs >= 1
    assert "net_arch" in spec.algo_kwargs["policy_kwargs"]


def test_hyperparameter_overrides_and_schedules():
    hp = apply_overrides(load_hyperparams("ppo", "self_excited"),
                         ["learning_rate:lin_1e-3", "policy_kwargs:{net_arch: [8], "
                          "activation_fn: relu}"])
    spec = split_hyperparams("ppo", hp)
    assert spec.algo_kwargs["learning_rate"](0.5) == pytest.approx(5e-4)
    import torch.nn as nn

    assert spec.algo_kwargs["policy_kwargs"]["activation_fn"] is nn.ReLU
    with pytest.raises(ValueError, match="unknown ppo hyperparameter"):
        split_hyperparams("ppo", {**hp, "not_a_key": 1})
    with pytest.raises(ValueError, match="KEY:VALUE"):
        apply_overrides(hp, ["gamma=0.9"])


# -- bad command lines --------------------------------------------------------------------------
@pytest.mark.parametrize("argv, needle", [
    (["--algo", "ppo", "--scene", "nope"], "invalid choice: 'nope'"),
    (["--algo", "dqn", "--scene", "paper"], "invalid choice: 'dqn'"),
    (["--algo", "ppo", "--scene", "paper", "-params", "bogus:1"], "unknown ppo hyperparameter"),
    (["--algo", "ppo", "--scene", "paper", "-n", "0"], "-n must be >= 1"),
    (["--algo", "ppo", "--scene", "paper", "--seed", "-1"], "seed must be an integer"),
    # more would reach the next run's block of plant seeds
    (["--algo", "ppo", "--scene", "paper", "--eval-episodes", "501"], "--eval-episodes <= 500"),
    # checked only by the constructors: the run folder made for them is removed again
    (["--algo", "ppo", "--scene", "paper", "-params", "env_kwargs:{foo: 1}"],
     "cannot build the training"),
    (["--algo", "ppo", "--scene", "paper", "-params", "normalize:{norm_obs: true, foo: 1}"],
     "cannot build the training"),
    # failed inside SB3 (after the run folder was written) or were taken silently
    (["--algo", "ppo", "--scene", "paper", "-params", "gamma:nan"],
     "gamma must be a number in (0, 1], got 'nan'"),
    (["--algo", "ppo", "--scene", "paper", "-params", "gamma:1.5"], "got 1.5"),
    (["--algo", "ppo", "--scene", "paper", "-params", "gae_lambda:-0.1"], "gae_lambda"),
    (["--algo", "ppo", "--scene", "paper", "-params", "clip_range:-1"], "clip_range"),
    (["--algo", "ppo", "--scene", "paper", "-params", "learning_rate:lin_0"], "'lin_0'"),
    (["--algo", "ppo", "--scene", "paper", "-params", "n_epochs:0"], "n_epochs"),
    (["--algo", "ppo", "--scene", "paper", "-params", "n_envs:2.9"], "n_envs"),
    (["--algo", "ppo", "--scene", "paper", "-params", "n_envs:true"], "got True"),
    (["--algo", "ppo", "--scene", "paper", "-params", "n_timesteps:.inf"], "n_timesteps"),
    (["--algo", "sac", "--scene", "paper", "-params", "ent_coef:auto_0"], "'auto_0'"),
    (["--algo", "ppo", "--scene", "paper", "-params", "env_kwargs:5"], "env_kwargs must be"),
    (["--algo", "ppo", "--scene", "paper", "-params", "gamma:[1,"], "cannot parse '[1,'"),
    (["--algo", "ppo", "--scene", "paper", "-params", "policy_kwargs:dict(net_arch=[64,"],
     "policy_kwargs string must be"),
    (["--algo", "ppo", "--scene", "paper", "--threads", "0"], "--threads must be >= 1, got 0"),
    (["--algo", "ppo", "--scene", "paper", "--threads", "-3"], "got -3"),
])
def test_train_cli_rejects_bad_input_clearly(argv, needle, capsys, tmp_path, monkeypatch):
    from stable_baselines3 import PPO, SAC

    def learn(self, *a, **k):  # an input taken silently fails fast instead of training
        raise AssertionError("bad input reached training")

    for cls in (PPO, SAC):
        monkeypatch.setattr(cls, "learn", learn)
    with pytest.raises(SystemExit) as exc:
        T.main([*argv, "-f", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert needle in err
    if "invalid choice: 'nope'" in needle:
        assert "self_excited" in err  # the valid names are listed
    assert not any(tmp_path.iterdir())  # nothing written


def test_numeric_strings_are_numbers_and_kinds_are_checked():
    """YAML 1.1 reads ``1e-3`` as a string, which SB3 failed on mid-training."""
    spec = split_hyperparams("ppo", {"ent_coef": "1e-3", "gamma": "0.98", "n_timesteps": "1e3"})
    assert spec.algo_kwargs["ent_coef"] == 0.001 and spec.algo_kwargs["gamma"] == 0.98
    assert spec.n_timesteps == 1000 and isinstance(spec.n_timesteps, int)
    assert split_hyperparams("sac", {"ent_coef": "auto_0.1"}).algo_kwargs["ent_coef"] == (
        "auto_0.1")
    for hp, needle in (({"n_steps": 64.0}, "n_steps must be an integer"),
                       ({"n_timesteps": 100.5}, "n_timesteps must be a whole"),
                       ({"normalize_advantage": 1}, "true or false"),
                       ({"ent_coef": "auto"}, "ent_coef must be")):  # SAC's, not PPO's
        with pytest.raises(ValueError, match=needle):
            split_hyperparams("ppo", hp)


@pytest.mark.parametrize("text, needle", [
    (None, "cannot read hyperparameter file"),  # a folder
    ("fricenv/StickSlip-v0: [1, 2\n", "is not valid YAML"),
    ("fricenv/StickSlip-v0: 5\n", "must be a mapping of hyperparameters, got 5"),
    ("[1, 2]\n", "must map environment ids to entries"),
])
def test_bad_hyperparameter_file_is_a_clear_error(text, needle, capsys, tmp_path):
    """A folder, broken YAML or a non-mapping entry was a traceback."""
    hp = tmp_path / "hp.yml"
    if text is None:
        hp.mkdir()
    else:
        hp.write_text(text)
    runs = tmp_path / "runs"
    with pytest.raises(SystemExit) as exc:
        T.main(["--algo", "ppo", "--scene", "paper", "--hyperparams", str(hp), "-f", str(runs)])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and needle in err and str(hp) in err
    assert not runs.exists()


@pytest.mark.parametrize("made", [False, True])
def test_failed_training_leaves_no_run_folder(made, monkeypatch, capsys, tmp_path):
    """A run that fails inside ``learn`` left config and logs but no model, and the folder
    then blocked the corrected rerun ("exists and is not empty")."""
    from stable_baselines3 import PPO

    def boom(self, *a, **k):
        raise RuntimeError("boom in learn")

    monkeypatch.setattr(PPO, "learn", boom)
    run = tmp_path / "run"
    if made:
        run.mkdir()
    argv = ["--algo", "ppo", "--scene", "paper", "-n", "32", "--eval-freq", "0",
            "--eval-episodes", "1", "--no-progress", "--run-dir", str(run),
            "-params", "n_envs:2", "n_steps:16", "batch_size:32"]
    with pytest.raises(SystemExit) as exc:
        T.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 1 and "boom in learn" in err and "removed" in err
    assert (run.exists() and not any(run.iterdir())) if made else not run.exists()
    T._check_folders(T.build_parser().parse_args(argv))  # a rerun is not blocked


def test_ctrl_c_keeps_the_model_trained_so_far(monkeypatch, capsys, tmp_path):
    """Ctrl-C left config and logs but no model (and the folder then failed evaluation):
    the model so far is saved, config.yml says the run was interrupted, exit status 130."""
    from stable_baselines3 import PPO

    collect = PPO.collect_rollouts
    calls = []

    def interrupted_second_rollout(self, *a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return collect(self, *a, **k)

    monkeypatch.setattr(PPO, "collect_rollouts", interrupted_second_rollout)
    run = tmp_path / "run"
    with pytest.raises(SystemExit) as exc:
        T.main(["--algo", "ppo", "--scene", "paper", "-n", "320", "--eval-freq", "0",
                "--eval-episodes", "1", "--no-progress", "--run-dir", str(run),
                "-params", "n_envs:2", "n_steps:16", "batch_size:32"])
    assert exc.value.code == 130 and "interrupted after 32 steps" in capsys.readouterr().err
    cfg = yaml.safe_load((run / "config.yml").read_text())
    assert cfg["interrupted"] is True and cfg["timesteps_done"] == 32
    assert cfg["n_timesteps"] == 320 and cfg["final_eval"]["return_mean"] < 0.0
    ctrl, _ = load_controller(run)
    assert ctrl.model.num_timesteps == 32


def test_sigterm_keeps_the_model_trained_so_far_as_ctrl_c_does(monkeypatch, capsys, tmp_path):
    """SIGTERM (timeout, SLURM, docker stop) ended the process in 0.03 s with no model."""
    import signal

    from stable_baselines3 import PPO

    collect = PPO.collect_rollouts
    calls = []

    def terminated_second_rollout(self, *a, **k):
        calls.append(1)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGTERM)  # (its handler runs in this thread, now)
        return collect(self, *a, **k)

    monkeypatch.setattr(PPO, "collect_rollouts", terminated_second_rollout)
    run = tmp_path / "run"
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    with pytest.raises(SystemExit) as exc:
        T.main(["--algo", "ppo", "--scene", "paper", "-n", "320", "--eval-freq", "0",
                "--eval-episodes", "1", "--no-progress", "--run-dir", str(run),
                "-params", "n_envs:2", "n_steps:16", "batch_size:32"])
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the handler is put back
    err = capsys.readouterr().err
    assert exc.value.code == 128 + signal.SIGTERM
    assert "interrupted after 32 steps by SIGTERM" in err
    cfg = yaml.safe_load((run / "config.yml").read_text())
    assert cfg["interrupted"] is True and cfg["stopped_by"] == "SIGTERM"
    assert cfg["timesteps_done"] == 32
    ctrl, _ = load_controller(run)
    assert ctrl.model.num_timesteps == 32


def test_train_folder_options_must_be_folders(capsys, tmp_path):
    """A --run-dir or -f naming a file was a NotADirectoryError traceback."""
    note = tmp_path / "notes.txt"
    note.write_text("keep me")
    for argv in (["--run-dir", str(note)], ["-f", str(note)]):
        with pytest.raises(SystemExit) as exc:
            T.main(["--algo", "ppo", "--scene", "paper", *argv])
        assert exc.value.code == 2 and "exists and is not a folder" in capsys.readouterr().err
    assert note.read_text() == "keep me"


def test_training_plants_are_the_runs_own_block(tmp_path, monkeypatch):
    """SB3 reseeds the env with the model's seed (plants s + i), so runs of neighbouring
    seeds shared most of their plants; the run's block (1000 s + i, in config.yml) is put
    back before training."""
    import fricenv.envs.sb3 as sb3

    first = []
    reset = sb3.StickSlipSB3VecEnv.reset

    def spy(self):
        first.append([int(s) for s in self._seeds])
        return reset(self)

    monkeypatch.setattr(sb3.StickSlipSB3VecEnv, "reset", spy)
    run = T.main(["--algo", "ppo", "--scene", "self_excited", "--seed", "2", "-n", "32",
                  "--eval-freq", "0", "--eval-episodes", "1", "--no-progress",
                  "--run-dir", str(tmp_path / "run"), "-params", "n_envs:4", "n_steps:8",
                  "batch_size:32"])
    lo, hi = yaml.safe_load((run / "config.yml").read_text())["train_env_seeds"]
    assert first[0] == list(range(lo, hi + 1)) == list(range(2000, 2004))


def test_cli_errors_as_users_see_them():
    res = _cli("fricenv_agents.train", "--algo", "a2c", "--scene", "self_excited")
    assert res.returncode == 2 and "invalid choice: 'a2c'" in res.stderr
    assert "Traceback" not in res.stderr
    res = _cli("fricenv_agents.evaluate", "--scene", "moon")
    assert res.returncode == 2 and "invalid choice: 'moon'" in res.stderr


def test_evaluate_cli_rejects_bad_input(capsys, tmp_path):
    for argv, needle in (
        (["--scene", "self_excited", "--seeds", "0"], "--seeds >= 1"),
        (["--runs", str(tmp_path / "missing")], "does not exist"),
        (["--controllers", "zero"], "give --scene"),
        # a named model of another scene was dropped from the table without a word
        (["--scene", "paper", "--models", str(ROOT / "agents/pretrained/ppo_self_excited.zip")],
         "trained on scene 'self_excited', not on 'paper'"),
    ):
        with pytest.raises(SystemExit) as exc:
            E.main([*argv, "--out", str(tmp_path / "out")])
        assert exc.value.code == 2
        assert needle in capsys.readouterr().err


def test_evaluate_reports_unusable_runs_clearly(ppo_run, capsys, tmp_path):
    """An unfinished run (config, no model) and a misnamed model file were tracebacks; a
    run's model.zip named on its own is evaluated with its run's config."""
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "config.yml").write_text((ppo_run / "config.yml").read_text())
    stray = tmp_path / "mystery.zip"
    stray.write_bytes((ppo_run / "model.zip").read_bytes())
    for argv, needle in ((["--runs", str(unfinished)], "an unfinished training run"),
                         (["--models", str(stray)], "unknown algorithm 'mystery'")):
        with pytest.raises(SystemExit) as exc:
            E.main([*argv, "--out", str(tmp_path / "out")])
        assert exc.value.code == 2 and needle in capsys.readouterr().err
    ctrl, cfg = load_controller(ppo_run / "model.zip")
    assert cfg["seed"] == 3 and ctrl.vecnormalize is not None


def test_evaluate_checks_models_and_out_before_writing(capsys, tmp_path):
    """A bare model of the wrong shape, a corrupt model and --out naming a file were
    tracebacks after the output folder was made."""
    bare = tmp_path / "ppo_bare.zip"  # no config beside it: its scene is unknown
    bare.write_bytes((ROOT / "agents/pretrained/ppo_self_excited.zip").read_bytes())
    corrupt = tmp_path / "ppo_corrupt.zip"
    corrupt.write_text("garbage")
    note = tmp_path / "notes.txt"
    note.write_text("keep me")
    out = tmp_path / "out"
    for argv, needle in (
        (["--scene", "paper", "--models", str(bare), "--out", str(out)],
         "the model's actions have shape (2,), scene 'paper' needs (1,)"),
        (["--scene", "self_excited", "--models", str(corrupt), "--out", str(out)],
         f"{corrupt}: cannot load the model"),
        (["--scene", "self_excited", "--out", str(note)], "exists and is not a folder"),
        (["--scene", "self_excited", "--out", str(note / "sub")], "exists and is not a folder"),
    ):
        with pytest.raises(SystemExit) as exc:
            E.main([*argv, "--controllers", "zero", "--seeds", "1", "--episodes", "1",
                    "--no-plots"])
        assert exc.value.code == 2 and needle in capsys.readouterr().err
    assert not out.exists() and note.read_text() == "keep me"


# -- baselines ----------------------------------------------------------------------------------
@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("incremental", [False, True])
@pytest.mark.parametrize("name", L.BASELINES)
def test_baseline_predict_shape_dtype_and_range(name, scene, incremental, tmp_path):
    kw = {"incremental": incremental}
    search = {"n_u0": 3, "n_nu": 3, "episodes": 2, "cache_dir": tmp_path}
    ctrl = B.make_baseline(name, scene, kw, seed=0, search_kwargs=search)
    env = gym.make(SCENE_ENV_IDS[scene], **kw)
    space = env.action_space
    obs, _ = env.reset(seed=0)
    a, state = ctrl.predict(obs, deterministic=True)
    assert state is None
    assert a.shape == space.shape and a.dtype == space.dtype == np.float32
    assert space.contains(a)
    batch = np.stack([obs] * 5)
    a5, _ = ctrl.predict(batch, state=None, episode_start=np.ones(5, bool))
    assert a5.shape == (5, *space.shape) and a5.dtype == np.float32
    assert np.all(np.abs(a5) <= 1.0)
    for _ in range(3):
        obs, *_ = env.step(ctrl.predict(obs)[0])  # the env accepts them
    with pytest.raises(ValueError, match="observation must have shape"):
        ctrl.predict(np.zeros(4, np.float32))


def test_settings_are_reached_in_absolute_and_incremental_mode():
    for incremental, steps in ((False, 1), (True, 12)):
        kw = {"incremental": incremental}
        env = gym.make(SCENE_ENV_IDS["self_excited"], **kw)
        obs, _ = env.reset(seed=0)
        ctrl = B.ConstantExcitation(1.3, 0.7, "self_excited", kw)
        for _ in range(steps):
            obs, *_ = env.step(ctrl.predict(obs)[0])
        assert obs[7] == pytest.approx(1.3, abs=1e-6) and obs[8] == pytest.approx(0.7, abs=1e-6)
        zero = B.ZeroExcitation("self_excited", kw)
        for _ in range(steps):
            obs, r, _, _, info = env.step(zero.predict(obs)[0])
        assert obs[7] == 0.0 and info["effort"] == 0.0


def test_rollout_scores_episodes_that_end_early_up_to_their_end():
    """Episodes that leave the observation box end at different steps; each one's metrics
    are those of the same episode run alone, and the others run on to the horizon."""
    from fricenv.envs import StickSlipEnv
    from fricenv.envs.scenes import SCENES as PRESETS

    scene = PRESETS["paper"].replace(x_limit=4.0, max_episode_steps=40)
    ctrl = B.ConstantExcitation(2.0, 0.1, scene)
    m = rollout(ctrl, scene, 10, 6)
    assert len(set(m.length.tolist())) > 1 and m.length.max() == 40  # some ended early
    for j in range(6):
        env = StickSlipEnv(scene=scene)
        obs, _ = env.reset(seed=10 + j)
        ret, stick, steps = 0.0, 0.0, 0
        for _ in range(40):
            obs, r, term, trunc, info = env.step(ctrl.predict(obs[None])[0][0])
            ret, stick, steps = ret + r, stick + info["stick_fraction"], steps + 1
            if term or trunc:
                break
        assert m.length[j] == steps
        assert m.ret[j] == pytest.approx(ret, rel=1e-12, abs=1e-12)
        assert m.stick_fraction[j] == pytest.approx(stick / steps, rel=1e-12, abs=1e-12)


def test_reports_and_baselines_follow_the_runs_env_kwargs():
    """A run trained with max_episode_steps in env_kwargs (a vector env argument) could not
    be evaluated, and the report printed the preset's dt, weights and V, not those used."""
    kw = {"control_dt": 1.0, "reward_weights": [1.0, 0.0, 0.0], "params": {"V": 0.5},
          "max_episode_steps": 50}
    sc = B.ActionMap("paper", kw).scene
    assert (sc.control_dt, sc.reward_weights, sc.params.V, sc.max_episode_steps) == (
        1.0, (1.0, 0.0, 0.0), 0.5, 50)
    assert B.ConstantExcitation(2.0, 0.5, "paper", kw).predict(np.zeros((1, 9)))[0].shape == (
        1, 1)
    md = S.markdown("paper", [], 1, 2, [], kw)
    for text in ("episodes of 50 control steps (dt = 1.0000)", "which is V = 0.5 ",
                 "effort = 1, 0, 0)", "Environment settings changed"):
        assert text in md
    assert "Environment settings changed" not in S.markdown("paper", [], 1, 2, [])


def test_random_baseline_is_seeded():
    obs = np.zeros((3, 9), np.float32)
    a = B.RandomActions("self_excited", seed=5).predict(obs)[0]
    b = B.RandomActions("self_excited", seed=5).predict(obs)[0]
    c = B.RandomActions("self_excited", seed=6).predict(obs)[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_best_constant_search_is_cached(tmp_path, monkeypatch):
    kw = {"n_u0": 3, "n_nu": 2, "episodes": 2, "cache_dir": tmp_path}
    res = B.search_best_constant("self_excited", **kw)
    assert (tmp_path / "best_constant_self_excited.json").exists()
    assert (tmp_path / "regime_map_self_excited.npz").exists()
    rets = [c["return_mean"] for c in res["candidates"]]
    assert rets == sorted(rets, reverse=True) and res["best"] == res["candidates"][0]
    assert any(c["u0"] == 0.0 for c in res["candidates"])  # zero excitation is a candidate

    import fricenv.sweep

    def boom(*a, **k):
        raise AssertionError("the cache was not used")

    monkeypatch.setattr(fricenv.sweep, "regime_map", boom)
    assert B.search_best_constant("self_excited", **kw) == res
    with pytest.raises(AssertionError, match="cache"):  # another search is not served stale
        B.search_best_constant("self_excited", **{**kw, "episodes": 3})
    monkeypatch.setattr(B, "SWEEP_ALGORITHM", B.SWEEP_ALGORITHM + 1)
    with pytest.raises(AssertionError, match="cache"):  # nor one by other physics code
        B.search_best_constant("self_excited", **kw)


def test_feedback_rule_fires_only_near_stick():
    ctrl = B.DitherOnStick("self_excited", threshold=0.2)
    obs = np.zeros((3, 9), np.float32)
    obs[:, 1] = [-1.0, -0.1, 0.0]  # v - V: far from stick, close, ...
    obs[2, 2] = 1.0  # ... stuck
    a, _ = ctrl.predict(obs)
    assert a[0, 0] == -1.0 and a[1, 0] == 1.0 and a[2, 0] == 1.0


# -- seeds and evaluation -----------------------------------------------------------------------
def test_evaluation_seeds_are_never_training_seeds():
    ev = set(L.eval_seeds(20, 100))
    for seed in (0, 1, 9_999):
        for first in (train_env_seed(seed), callback_env_seed(seed)):
            assert not ev & set(range(first, first + 500))
    assert eval_env_seed(0) >= train_env_seed(MAX_TRAIN_SEED - 1) + SEED_STRIDE
    with pytest.raises(ValueError, match="used in training"):
        L.check_disjoint({"train_env_seeds": [eval_env_seed(1), eval_env_seed(1) + 3]}, 2, 2,
                         "run")


def test_evaluate_writes_its_table_for_baselines(tmp_path):
    out = tmp_path / "eval"
    [table] = E.main(["--scene", "self_excited", "--controllers", "zero", "random",
                      "feedback", "--seeds", "2", "--episodes", "2", "--out", str(out)])
    text = table.read_text()
    assert table == out / "self_excited.md"
    for needle in ("zero excitation", "random actions", "feedback", "stick-time fraction",
                   "RMS relative velocity", "actuation effort", "return", "| 4 |"):
        assert needle in text, needle
    res = json.loads((out / "self_excited_results.json").read_text())
    zero = res["controllers"]["zero"]
    assert zero["n"] == 4 and zero["stick_fraction"]["mean"] > 0.3  # it does stick-slip
    assert res["controllers"]["feedback"]["stick_fraction"]["mean"] < 0.1
    assert (out / "self_excited_time_history.png").exists()


def test_evaluate_a_trained_run_with_learning_curves(ppo_run, tmp_path):
    out = tmp_path / "eval"
    [table] = E.main(["--runs", str(ppo_run), "--controllers", "zero", "--seeds", "1",
                      "--episodes", "2", "--out", str(out)])
    text = table.read_text()
    assert "PPO (1 training seed)" in text
    # one run: one wall time and one step count, not a range from a value to itself
    assert re.search(r"training wall time \d+ s per run \(256 steps", text), text
    assert "Bar" not in text and "met**" not in text  # measurements only, no pass marks
    assert (out / "self_excited_learning_curves.png").exists()


@pytest.mark.parametrize(("values", "spec", "text"), [
    ([152.2, 151.8], ".0f", "152"), ([35.0, 55.4], ".0f", "35–55"), ([256], "", "256"),
    ([300, 301], "", "300–301")])
def test_span_gives_one_value_when_all_agree(values, spec, text):
    assert S._span(values, spec) == text


def test_results_pages_state_measurements_only():
    for page in (ROOT / "docs" / "results").glob("*.md"):
        text = page.read_text()
        assert "- Bar (" not in text and "**met**" not in text, page.name
        assert not re.search(r"\b(\d+)–\1 s\b", text), page.name


def test_evaluate_says_what_it_is_doing_unless_quiet(capsys, tmp_path):
    argv = ["--scene", "self_excited", "--controllers", "zero", "--seeds", "1",
            "--episodes", "1", "--no-plots"]
    E.main([*argv, "--out", str(tmp_path / "a")])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("python -m")]
    assert lines[0].startswith("python -m fricenv_agents.evaluate [0 s]: self_excited: "
                               "running 1 controllers"), err
    assert "self_excited episodes" in err  # the bar over the batches of episodes
    assert "wrote" in lines[-1]
    E.main([*argv, "--out", str(tmp_path / "b"), "--quiet"])
    captured = capsys.readouterr()
    assert captured.err == ""
    assert "zero excitation" in captured.out  # the table still prints


def test_train_says_what_it_is_doing_unless_quiet(capsys, tmp_path):
    argv = ["--algo", "ppo", "--scene", "paper", "-n", "32", "--eval-freq", "0",
            "--eval-episodes", "1", "-params", "n_envs:4", "n_steps:8", "batch_size:32"]
    T.main([*argv, "--run-dir", str(tmp_path / "a")])
    err = capsys.readouterr().err
    stages = [line.split(": ", 1)[1] for line in err.splitlines()
              if line.startswith("python -m fricenv_agents.train [")]
    assert [s.split()[0] for s in stages] == ["checking", "building", "training", "saving"]
    assert "train: 100%" in err  # the progress bar
    T.main([*argv, "--run-dir", str(tmp_path / "b"), "--quiet"])
    captured = capsys.readouterr()
    assert captured.err == ""
    assert "training wall time" in captured.out


def test_tensorboard_without_the_package_is_a_clear_error(capsys, tmp_path):
    try:
        import tensorboard  # noqa: F401

        pytest.skip("tensorboard is installed")
    except ImportError:
        pass
    with pytest.raises(SystemExit):
        T.main(["--algo", "ppo", "--scene", "paper", "--tensorboard", "-f", str(tmp_path)])
    assert "pip install tensorboard" in capsys.readouterr().err


def test_best_constant_search_with_unequal_tone_gains():
    from fricenv.envs.scenes import SCENES as ALL

    single = ALL["self_excited"].replace(name="single_tone", tone_gains=(1.0, 0.0))
    res = B.search_best_constant(single, n_u0=3, n_nu=2, episodes=2)
    # One tone of amplitude 2 at eta = 6 quenches this plant (docs/model.md).
    assert res["best"]["u0"] == 2.0 and res["best"]["stationary_stick_fraction"] == 0.0


def test_pretrained_model_loads_and_acts():
    path = ROOT / "agents" / "pretrained" / "ppo_self_excited.zip"
    ctrl, cfg = load_controller(path)
    assert cfg["scene"] == "self_excited" and ctrl.vecnormalize is not None
    obs, _ = gym.make(SCENE_ENV_IDS["self_excited"]).reset(seed=eval_env_seed(0))
    a, _ = ctrl.predict(obs)
    assert a.shape == (2,) and a.dtype == np.float32


@pytest.mark.slow
def test_short_ppo_training_meets_the_bar(tmp_path):
    """300k PPO steps (under a minute here) already cut stick time >= 90 % and beat the
    best constant excitation on return, on evaluation episodes."""
    run = tmp_path / "run"
    res = _cli("fricenv_agents.train", "--algo", "ppo", "--scene", "self_excited", "--seed", "0",
               "-n", "300000", "--run-dir", str(run), "--no-progress")
    assert res.returncode == 0, res.stderr
    out = tmp_path / "eval"
    E.main(["--runs", str(run), "--controllers", "zero", "best_constant", "--seeds", "5",
            "--episodes", "4", "--out", str(out), "--no-plots"])
    c = json.loads((out / "self_excited_results.json").read_text())["controllers"]
    stick = c["ppo"]["stick_fraction"]["mean"]
    assert stick <= 0.1 * c["zero"]["stick_fraction"]["mean"]
    assert c["ppo"]["ret"]["mean"] > c["best_constant"]["ret"]["mean"]
