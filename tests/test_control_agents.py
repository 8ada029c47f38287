"""The exact-model MPC baseline and the state estimate it plans from without a binding."""

from __future__ import annotations

import json
import re
import shutil
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from fricenv_agents.mpc import MPPIController
from fricenv_agents.rollouts import rollout

import fricenv  # noqa: F401  (registers the environments)
from fricenv.core import new_workspace
from fricenv.envs.observation import plants_from_observations
from fricenv.envs.state import PL_CTRL, PL_S, PL_WORK
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv
from fricenv.layout import S_MODE, S_PHI1, S_PHI2, S_T, S_V, S_X

SMALL = {"horizon": 4, "samples": 16}


def test_mpc_predict_shapes_and_determinism():
    env = gym.make("fricenv/StickSlipStribeck-v0")
    obs, _ = env.reset(seed=0)
    a1 = [MPPIController("stribeck", seed=3, **SMALL).predict(obs)[0] for _ in range(2)]
    assert a1[0].shape == (2,) and a1[0].dtype == np.float32
    assert np.array_equal(a1[0], a1[1]) and env.action_space.contains(a1[0])
    ctrl = MPPIController("paper", **SMALL)  # frequency only: one action
    batch = np.stack([gym.make("fricenv/StickSlip-v0").reset(seed=s)[0] for s in range(3)])
    act, state = ctrl.predict(batch, episode_start=np.ones(3, bool))
    assert act.shape == (3, 1) and state is None and np.all(np.abs(act) <= 1.0)
    for bad, err in (({"horizon": 0}, ValueError), ({"samples": 1}, ValueError),
                     ({"noise_std": 0.0}, ValueError), ({"temperature": "hot"}, TypeError)):
        with pytest.raises(err):
            MPPIController("paper", **bad)


def test_mpc_bound_to_the_plants_beats_no_control():
    """With the exact states (bound by ``rollout``) a short MPC already cuts the stick."""
    scene = gym.make("fricenv/StickSlipViscous-v0").unwrapped.scene.replace(max_episode_steps=40)
    zero = rollout(_Zero(), scene, 100, 2)
    mpc = rollout(MPPIController(scene, horizon=6, samples=32), scene, 100, 2)
    assert mpc.ret.mean() > zero.ret.mean() + 5.0
    assert mpc.stick_fraction.mean() < 0.5 * zero.stick_fraction.mean()


class _Zero:
    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        a = np.zeros((obs.shape[0], 2), np.float32)
        a[:, 0] = -1.0  # u0 = 0
        return a, state


def test_mpc_needs_the_state_under_partial_observation():
    kw = {"observe": ("x", "phases")}
    env = StickSlipEnv(scene="self_excited", **kw)
    obs, _ = env.reset(seed=0)
    ctrl = MPPIController("self_excited", kw, **SMALL)
    with pytest.raises(ValueError, match="bind it to the environment"):
        ctrl.predict(obs)
    ctrl.bind(env)
    assert ctrl.predict(obs)[0].shape == (2,)
    with pytest.raises(TypeError):
        ctrl.bind(object())


def test_mpc_models_the_actuator_and_runs_on_noisy_observations():
    kw = {"actuator_rate": 0.1, "obs_noise": 0.02}
    vec = StickSlipVectorEnv(num_envs=2, scene="self_excited", **kw)
    obs, _ = vec.reset(seed=0)
    ctrl = MPPIController("self_excited", kw, **SMALL)
    assert ctrl._roll is None and ctrl.describe()["state"] == "from observation"
    for _ in range(3):
        obs = vec.step(ctrl.predict(obs)[0])[0]
    assert ctrl._roll.actuated


def test_state_estimate_from_a_full_observation():
    env = StickSlipEnv(scene="paper")
    env.reset(seed=1)
    for _ in range(7):
        obs = env.step(np.array([0.3], np.float32))[0]
    true = env.get_state()
    plants, cmds = plants_from_observations(obs[None], true.plant[:PL_S], (1.0, 1.0))
    S, T = plants[0, PL_S:PL_CTRL], true.plant[PL_S:PL_CTRL]
    assert S[S_T] == 0.0 and S[S_MODE] == T[S_MODE]
    for k in (S_X, S_V, S_PHI1, S_PHI2):
        assert S[k] == pytest.approx(T[k], abs=1e-5)
    assert np.array_equal(cmds[0], plants[0, PL_CTRL:PL_WORK])
    # a fresh workspace: empty caches, its flags and step budget
    assert np.array_equal(plants[0, PL_WORK:], new_workspace(extrema=False), equal_nan=True)


def test_held_out_boxes_lie_beyond_the_training_ranges():
    from fricenv_agents.benchmark import HELD_OUT, held_out_scene

    from fricenv.envs.scenes import SCENES

    for scene in ("paper", "self_excited", "stribeck", "viscous"):
        train = SCENES[scene].ranges
        below = held_out_scene(scene, "below").ranges
        above = held_out_scene(scene, "above").ranges
        for key, (lo, hi) in train.items():
            if key in HELD_OUT:
                assert 0.0 <= below[key][0] < below[key][1] < lo
                assert hi < above[key][0] < above[key][1]
            else:
                assert below[key] == above[key] == (lo, hi)


def test_benchmark_writes_its_tables_with_a_tiny_robust_run(tmp_path):
    """The whole benchmark on one scene, with few-step PPOs (one trained with randomised
    plants, sensor noise and delay) standing in for the real runs (the numbers mean
    nothing; the layout, the intervals, the per-episode CSV and the figures are checked)."""
    import csv

    from fricenv_agents import benchmark as BM
    from fricenv_agents import train as T

    runs = tmp_path / "runs"
    robust = "env_kwargs:{randomize: true, obs_noise: 0.02, obs_delay: 1}"
    for group, extra in (("ppo_robust", [robust]), ("ppo", [])):
        T.main(["--algo", "ppo", "--scene", "self_excited", "-n", "64", "--seed", "1",
                "--run-dir", str(runs / f"{group}_self_excited_s1"), "--eval-freq", "0",
                "--eval-episodes", "1", "--no-progress", "-params", "n_envs:2",
                "n_steps:32", "batch_size:32", "n_epochs:1", *extra])
    out = tmp_path / "out"
    table = BM.main(["--runs", str(runs), "--out", str(out), "--scenes", "self_excited",
                     "--seeds", "2", "--episodes", "2", "--grid", "2",
                     "--search-episodes", "2", "--max-steps", "30"])
    text = table.read_text()
    for needle in ("### Return (IQM [95 % CI])", "### Stick-time fraction (IQM [95 % CI])",
                   "MPC (MPPI, exact model)", "held out below", "noise + delay",
                   "PPO, robust training (randomised plants and sensors; 1 training seed)",
                   "control_generalisation.png", "gap to the MPC [95 % CI]",
                   "IQM of each training seed", "retention, held out (worst side)",
                   "control_profiles.png", "control_benchmark_episodes.csv"):
        assert needle in text, needle
    # every cell of the main tables is "IQM [lo, hi]" with lo <= IQM <= hi, on one line
    # (no-break spaces)
    main = text[:text.index("### Learned controllers")]
    cells = re.findall(r"\| (-?[\d.]+)\u00a0\[(-?[\d.]+),\u00a0(-?[\d.]+)\]", main)
    assert len(cells) == 2 * 7
    assert all(float(lo) <= float(est) <= float(hi) for est, lo, hi in cells)
    assert re.search(r"\| [-+]?[\d.]+\u00a0%\u00a0\[[-\d.]+,\u00a0[-\d.]+\] \| (yes|no) \|",
                     text)
    assert "Stick cut against zero excitation on the same episodes, per condition" in text
    res = json.loads((out / "control_benchmark.json").read_text())
    assert set(res["scenes"]["self_excited"]) == {"zero", "random", "best_constant",
                                                  "feedback", "mpc", "ppo", "ppo_robust"}
    gen = res["generalisation"]["self_excited"]
    assert set(gen) == {"in range", "held out below", "held out above", "noise + delay"}
    assert set(gen["in range"]) == {"zero", "mpc", "ppo", "ppo_robust"}
    assert set(gen["noise + delay"]) == {"zero", "mpc", "mpc_filter", "ppo", "ppo_robust"}
    # the filtered MPC's retention is against the bound MPC's noise-free cut
    filt = res["cuts_and_retentions"]["self_excited"]["mpc_filter"]
    assert set(filt) == {"noise + delay", "retention, noise + delay"}
    assert set(gen["held out below"]) == {"zero", "ppo", "ppo_robust"}  # (MPC: exact plant)
    assert gen["noise + delay"]["mpc"]["label"].endswith("state from the observation)")
    ci = res["scenes"]["self_excited"]["ppo"]["iqm_ci"]["ret"]
    assert ci["lo"] <= ci["estimate"] <= ci["hi"]
    assert set(res["gap_to_mpc"]["self_excited"]) == {"ppo", "ppo_robust"}
    assert set(res["cuts_and_retentions"]["self_excited"]["ppo_robust"]) == {
        *BM.CONDITIONS, "retention, held out", "retention, noise + delay"}
    assert set(res["versions"]) == {"fricenv", "numpy", "numba", "torch",
                                    "stable_baselines3", "python"}
    with open(out / "control_benchmark_episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    from fricenv_agents.benchmark_records import CSV_COLUMNS

    assert tuple(rows[0]) == CSV_COLUMNS
    # what ran: 7 controllers on the nominal episodes, 4 in range, 5 under noise + delay
    # (the filtered MPC too), 3 in each held-out box (not the MPC), one model each,
    # 2 evaluation seeds x 2 episodes
    assert len(rows) == (7 + 4 + 5 + 2 * 3) * 2 * 2
    n_json = sum(len(e["per_episode"]["ret"]) for e in res["scenes"]["self_excited"].values())
    n_json += sum(len(e["per_episode"]["ret"]) for c in gen.values() for e in c.values())
    assert len(rows) == n_json
    import numpy
    import stable_baselines3

    assert {r["numpy_version"] for r in rows} == {numpy.__version__}
    assert {r["stable_baselines3_version"] for r in rows} == {stable_baselines3.__version__}
    assert all(r["fricenv_version"] and r["torch_version"] and r["numba_version"]
               and r["python_version"] for r in rows)
    ppo = [r for r in rows if r["controller"] == "ppo" and r["condition"] == "nominal"]
    assert [(r["eval_seed"], r["episode"]) for r in ppo] == [("0", "0"), ("0", "1"),
                                                              ("1", "0"), ("1", "1")]
    assert {r["training_run"] for r in ppo} == {"ppo_self_excited_s1"}
    assert [int(r["plant_seed"]) for r in ppo] == [10_000_000, 10_000_001, 10_001_000,
                                                   10_001_001]
    assert [float(r["ret"]) for r in ppo] == res["scenes"]["self_excited"]["ppo"][
        "per_episode"]["ret"]
    for fig in ("control_benchmark.png", "control_profiles.png",
                "control_generalisation.png"):
        assert (out / fig).stat().st_size > 1000, fig
    # the throughput section, as fricenv_agents.throughput measures it
    assert "### Throughput" in text
    tp = res["throughput"]
    assert tp["vector"] and tp["ppo"]


def test_benchmark_scenes_in_worker_processes_score_as_in_one(tmp_path):
    """``--jobs 2`` evaluates the scenes in two spawned processes: the same episodes, the
    same seeds, so the same scores as one process."""
    from fricenv_agents import benchmark as BM

    argv = ["--runs", str(tmp_path / "none"), "--scenes", "paper", "self_excited",
            "--seeds", "1", "--episodes", "2", "--grid", "2", "--search-episodes", "2",
            "--max-steps", "8", "--no-generalisation", "--no-throughput"]
    scores = []
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs{jobs}"
        BM.main([*argv, "--out", str(out), "--jobs", jobs])
        res = json.loads((out / "control_benchmark.json").read_text())
        scores.append({(s, k): e["per_episode"]["ret"] for s, r in res["scenes"].items()
                       for k, e in r.items()})
    assert scores[0] == scores[1] and len(scores[0]) == 2 * 5


def test_benchmark_rows_are_a_registry():
    """Adding a controller is one ``Row``; trained rows name what the training script runs."""
    from fricenv_agents import benchmark as BM

    groups = BM.training_groups()
    noise = {k: round(BM.ROBUST_NOISE_FACTOR * v, 9) for k, v in BM.NOISE.items()}
    assert groups["ppo_robust"] == ("ppo", {"randomize": True, "obs_noise": noise,
                                            "obs_delay": 1, "randomize_sensors": True})
    assert BM.ROBUST_NOISE_FACTOR > 1  # the benchmark's noise lies inside the training's
    assert set(groups) == {"ppo", "ppo_robust", "sac"}
    zero = BM.ROWS[0]
    with pytest.raises(ValueError, match="distinct keys"):
        BM.check_rows([zero, zero])
    with pytest.raises(ValueError, match="the 'zero' row only in"):
        BM.check_rows([BM.Row("zero", "zero", BM.baseline("zero")), BM.ROWS[4]])
    with pytest.raises(ValueError, match="unknown conditions"):
        BM.check_rows([zero, BM.Row("x", "x", BM.per_seed(BM.exact_mpc), ("windy",))])
    with pytest.raises(ValueError, match="retention_of names no row: 'nope'"):
        BM.check_rows([zero, BM.Row("x", "x", BM.per_seed(BM.exact_mpc),
                                    retention_of="nope")])
    assert BM.build_parser().get_default("seeds") == 10
    assert BM.build_parser().get_default("runs") == BM.PRETRAINED_RUNS


def test_training_script_trains_the_rows_groups(tmp_path):
    """scripts/train_control_benchmark.py trains each trained row with its env kwargs."""
    import importlib.util
    from pathlib import Path

    from fricenv_agents import benchmark as BM
    from fricenv_agents.config import apply_overrides

    path = Path(__file__).resolve().parents[1] / "scripts" / "train_control_benchmark.py"
    spec = importlib.util.spec_from_file_location("train_control_benchmark", path)
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    todo = script.jobs(["ppo_robust", "sac"], ["viscous"], 2, 3, tmp_path)
    assert [run.name for run, _ in todo] == [
        *(f"ppo_robust_viscous_s{s}" for s in range(3)), "sac_viscous_s0", "sac_viscous_s1"]
    cmd = todo[0][1]
    assert cmd[cmd.index("--algo") + 1] == "ppo"
    params = cmd[cmd.index("-params") + 1:]
    assert apply_overrides({}, params)["env_kwargs"] == BM.ROBUST_ENV_KWARGS
    assert "-params" not in todo[-1][1]


def test_the_benchmarks_trained_runs_ship_complete():
    """Every trained row has its 5 training seeds per scene in the shipped folder, each a
    finished run of its algorithm and env kwargs, with no machine path in its config; the
    training script, run on the shipped folder, has nothing left to do."""
    import subprocess
    import sys
    from pathlib import Path

    import yaml
    from fricenv_agents import benchmark as BM
    from fricenv_agents.config import load_hyperparams
    from fricenv_agents.runs import observation_names

    for group, (algo, kw) in BM.training_groups().items():
        for scene in BM.BENCH_SCENES:
            runs = BM.run_group(BM.PRETRAINED_RUNS, group, scene)
            assert [r.name for r in runs] == [f"{group}_{scene}_s{s}" for s in range(5)]
            expected = kw or load_hyperparams(algo, scene).get("env_kwargs") or {}
            for run in runs:
                text = (run / "config.yml").read_text()
                assert not re.search(r"/(work|root|home|tmp)/", text), run
                cfg = yaml.safe_load(text)
                assert (cfg["algo"], cfg["scene"]) == (algo, scene), run
                assert cfg["env_kwargs"] == expected, run
                assert cfg["observation"] == observation_names(scene, expected), run
                assert cfg["timesteps_done"] >= cfg["n_timesteps"], run
    root = Path(__file__).resolve().parents[1]
    page = (root / "docs" / "results" / "control_benchmark.json").read_text()
    assert not re.search(r"/(work|root|home|tmp)/", page)  # (run paths: repository-relative)
    out = subprocess.run([sys.executable, "scripts/train_control_benchmark.py", "--dry-run"],
                         cwd=root, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.startswith("0 runs to do"), out.stdout


@pytest.mark.parametrize("scene", ["paper", "self_excited", "stribeck", "viscous"])
def test_pretrained_policy_of_every_scene_loads_and_cuts_the_stick(scene):
    from pathlib import Path

    from fricenv_agents.baselines import ZeroExcitation
    from fricenv_agents.layout import eval_env_seed
    from fricenv_agents.runs import load_controller

    from fricenv.envs.scenes import SCENES

    path = Path(__file__).resolve().parents[1] / "agents" / "pretrained" / f"ppo_{scene}.zip"
    ctrl, cfg = load_controller(path)
    assert cfg["scene"] == scene and ctrl.vecnormalize is not None
    short = SCENES[scene].replace(max_episode_steps=60)
    ppo = rollout(ctrl, short, eval_env_seed(0), 2)
    zero = rollout(ZeroExcitation(short), short, eval_env_seed(0), 2)
    assert ppo.stick_fraction.mean() < 0.5 * zero.stick_fraction.mean()


def test_a_trained_models_episodes_run_side_by_side_as_seed_by_seed():
    """``run_entry`` runs all of a trained model's evaluation seeds in one vector env: the
    same plants, so the same scores as one rollout per seed."""
    from pathlib import Path

    import fricenv_agents
    from fricenv_agents.layout import eval_env_seed
    from fricenv_agents.runs import load_controller
    from fricenv_agents.scoring import Entry, run_entry

    model = Path(fricenv_agents.__file__).parent / "pretrained" / "ppo_self_excited.zip"
    ctrl, _ = load_controller(model)
    entry = Entry("ppo", "PPO", "trained", [lambda k: ctrl])
    kw = {"max_episode_steps": 12}
    run_entry(entry, "self_excited", kw, 3, 2)
    per_seed = [rollout(ctrl, "self_excited", eval_env_seed(k), 2, kw) for k in range(3)]
    for field in ("ret", "stick_fraction", "effort"):
        np.testing.assert_allclose(getattr(entry.scores, field),
                                   np.concatenate([getattr(m, field) for m in per_seed]),
                                   rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("kind", ["unbound", "bound", "filtered"])
def test_the_mpcs_refuse_observations_no_environment_gives(kind):
    """NaN, a value beyond the observation box, a stick flag of 0.5 and an empty batch are
    refused by name before any plan is made, bound or not; the controller then plans on."""
    from fricenv_agents.estimation import FilteredMPC

    from fricenv.envs.observation import CHANNELS

    env = StickSlipEnv(scene="self_excited")
    obs, _ = env.reset(seed=0)
    if kind == "filtered":
        ctrl: Any = FilteredMPC("self_excited", particles=8, **SMALL)
    else:
        ctrl = MPPIController("self_excited", exact_state=kind == "bound", **SMALL)
        ctrl.bind(env)
    x, stick = CHANNELS.index("x"), CHANNELS.index("stick")
    for value, channel, match in ((np.nan, x, r"channel 'x' = nan"),
                                  (1e30, x, r"channel 'x' = 1e\+30"),
                                  (0.5, stick, r"channel 'stick' = 0.5")):
        bad = obs.copy()
        bad[channel] = value
        with pytest.raises(ValueError, match=match):
            ctrl.predict(bad)
    with pytest.raises(ValueError, match="empty batch"):
        ctrl.predict(np.zeros((0, obs.size), np.float32))
    assert ctrl.predict(obs)[0].shape == (2,)


def test_a_model_runs_only_where_its_channels_are_the_environments(tmp_path):
    """Two layouts of nine channels have the same shape: loading compares the channel
    names a run records with the environment's and names the first that differs."""
    import yaml
    from fricenv_agents.benchmark import PRETRAINED_RUNS
    from fricenv_agents.runs import check_observation, observation_names
    from fricenv_agents.scoring import trained_entries

    run = tmp_path / "ppo_paper_s0"
    shutil.copytree(PRETRAINED_RUNS / "ppo_paper_s0", run)
    cfg = yaml.safe_load((run / "config.yml").read_text())
    names = observation_names("paper", cfg["env_kwargs"])
    assert cfg["observation"] == names
    assert len(trained_entries([run], "paper")[0]) == 1
    cfg["observation"] = [names[1], names[0], *names[2:]]
    (run / "config.yml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    with pytest.raises(ValueError, match=r"ppo_paper_s0: the model observes channels .*"
                       r"channel 0 is 'v_rel' for the model, 'x' for the environment"):
        trained_entries([run], "paper")
    with pytest.raises(ValueError, match=r"channel 5 is '\(none\)' for the model"):
        check_observation({"observation": names[:5]}, names, "m.zip")
    check_observation({}, names, "m.zip")  # (a bare model file: its shape is checked)


def test_a_damaged_model_file_is_named_in_the_error(tmp_path):
    """A truncated model, a garbled normalisation pickle or config gave SB3's, pickle's or
    YAML's error without the file's name."""
    import shutil
    from pathlib import Path

    from fricenv_agents.runs import load_controller

    src = Path(__file__).resolve().parents[1] / "agents" / "pretrained"
    for suffix in (".zip", "_vecnormalize.pkl", ".yml"):
        shutil.copy(src / f"ppo_paper{suffix}", tmp_path / f"ppo_paper{suffix}")
    model = tmp_path / "ppo_paper.zip"
    load_controller(model)  # the copy loads
    damage = [(model, model.read_bytes()[:200], r"ppo_paper\.zip: cannot load the ppo model"),
              (tmp_path / "ppo_paper_vecnormalize.pkl", b"\x80\x04garbage",
               r"ppo_paper_vecnormalize\.pkl: cannot load the observation normalisation"),
              (tmp_path / "ppo_paper.yml", b"scene: [paper\n",
               r"ppo_paper\.yml: cannot read the run config"),
              (tmp_path / "ppo_paper.yml", b"- a list\n", r"ppo_paper\.yml: .* a mapping")]
    for path, data, match in damage:
        good = path.read_bytes()
        path.write_bytes(data)
        with pytest.raises(ValueError, match=match):
            load_controller(model)
        path.write_bytes(good)
