"""Closing PPO's gap to the tuned MPC: the new runs scored on the benchmark's episodes and
compared with the tuned MPC as the shipped runs are."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from fricenv_agents import mpc_compare as C
from fricenv_agents import mpc_gap as G
from fricenv_agents.benchmark_records import read_episodes
from fricenv_agents.layout import EVAL_SEED_BASE, eval_seeds

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"


def _config(run: Path, **extra: object) -> None:
    run.mkdir(parents=True)
    cfg = {"algo": "ppo", "scene": "stribeck", "n_timesteps": 1_000_000,
           "timesteps_done": 1_003_520, "env_kwargs": {"max_episode_steps": 100},
           "hyperparams": {"learning_rate": 3e-4}, "train_seconds": 120.0,
           "hyperparams_file": "agents/hyperparams/ppo_short.yml", **extra}
    (run / "config.yml").write_text(yaml.safe_dump(cfg))
    (run / "model.zip").touch()


def test_runs_are_found_by_scene_in_seed_order(tmp_path: Path) -> None:
    for seed in (10, 2, 0):
        _config(tmp_path / f"ppo_stribeck_s{seed}")
    _config(tmp_path / "ppo_viscous_s1")
    (tmp_path / "ppo_stribeck_s3").mkdir()  # (no config.yml: not a finished run)
    _config(tmp_path / "ppo_stribeck_s4")
    (tmp_path / "ppo_stribeck_s4" / "model.zip").unlink()  # (training under way)
    assert [p.name for p in G.scene_runs(tmp_path, "stribeck")] == [
        "ppo_stribeck_s0", "ppo_stribeck_s2", "ppo_stribeck_s10"]


def test_the_recipe_and_its_compute_come_from_the_runs_configs(tmp_path: Path) -> None:
    warm = {"rounds": 40, "steps": 15, "env_steps": 9600, "seconds": 300.0}
    for seed, secs in ((0, 100.0), (1, 140.0)):
        _config(tmp_path / f"ppo_viscous_s{seed}", train_seconds=secs,
                env_kwargs={"max_episode_steps": 50}, warm_start=warm)
    r = G.recipe(G.scene_runs(tmp_path, "viscous"))
    assert r["episode_steps"] == 50 and r["timesteps"] == 1_000_000
    assert r["train_seconds"] == [100.0, 140.0]
    assert r["warm_start"] == {"rounds": 40, "steps": 15, "labels": 9600,
                               "seconds": [300.0, 300.0]}
    text = G.describe(r)
    assert "9600 MPC labels" in text and "first 15 intervals" in text
    assert "2.0 min of PPO per run" in text and "5.0 min per run" in text
    plain = G.recipe([tmp_path / "ppo_viscous_s0"])
    plain["warm_start"] = None
    assert "DAgger" not in G.describe(plain)


def test_a_run_that_trained_on_an_evaluation_episode_is_refused(tmp_path: Path) -> None:
    run = tmp_path / "ppo_stribeck_s0"
    _config(run, train_env_seeds=[EVAL_SEED_BASE, EVAL_SEED_BASE + 15])
    with pytest.raises(ValueError, match="was used in training"):
        G.score_runs([run], "stribeck", 10, 5)
    with pytest.raises(ValueError, match="no runs of scene"):
        G.score_runs([], "stribeck", 10, 5)


def test_the_page_is_made_from_the_csvs_without_scoring(tmp_path: Path) -> None:
    """A scene already in ``--out``'s CSV is not scored again. With the benchmark's own PPO
    rows standing in for the new runs, before and after agree, and both are the
    comparison ``mpc_compare`` publishes."""
    bench = read_episodes(C.DEFAULT_CSV)
    stand_in = [dict(r, controller=G.KEY) for r in bench if r["controller"] == "ppo"
                and r["condition"] == "nominal" and r["scene"] == "stribeck"]
    out = tmp_path / "out"
    out.mkdir()
    C._write_csv(out / G.CSV_NAME, stand_in)
    runs = tmp_path / "runs"
    _config(runs / "ppo_stribeck_s0")
    page = G.main(["--scenes", "stribeck", "--runs", str(runs), "--out", str(out)])
    text = page.read_text()
    assert "| `stribeck` | before |" in text and "| `stribeck` | after |" in text
    assert "On `stribeck` PPO trained on short episodes is" in text
    assert "100 intervals" in text and "1 PPO runs trained on short episodes" in text
    assert "1M PPO steps" in text
    saved = json.loads((out / "mpc_gap.json").read_text())["scenes"]["stribeck"]
    assert saved["before"] == saved["after"]
    published = json.loads((RESULTS / "mpc_compare.json").read_text())["tuned"]["stribeck"]
    assert saved["after"]["gap_iqm"] == pytest.approx(published["gap_iqm"])
    assert saved["after"]["win_share"] == pytest.approx(published["win_share"])


@pytest.mark.slow
def test_new_runs_are_scored_on_the_evaluation_episodes(tmp_path: Path) -> None:
    """A short training, scored on 2 x 2 evaluation episodes: one row per run and episode,
    on the benchmark's plant seeds, under the new controller key."""
    from fricenv_agents import train as T

    run = tmp_path / "ppo_self_excited_s3"
    T.main(["--algo", "ppo", "--scene", "self_excited", "--seed", "3", "-n", "64",
            "--no-progress", "--eval-freq", "0", "--eval-episodes", "2", "--quiet",
            "--run-dir", str(run), "-params", "n_steps:32", "batch_size:32", "n_envs:2"])
    rows = G.score_runs(G.scene_runs(tmp_path, "self_excited"), "self_excited", 2, 2)
    assert {r["controller"] for r in rows} == {G.KEY}
    assert sorted(r["plant_seed"] for r in rows) == sorted(eval_seeds(2, 2))
    assert all(r["training_run"] == run.name and r["length"] == 400 for r in rows)


def test_the_short_episode_recipes_are_valid_runs_of_their_scenes() -> None:
    """Every entry of ``ppo_short.yml`` passes the training's checks, trains on episodes
    shorter than its scene's, and a warm start labels no more intervals than an episode
    has (``dagger`` would refuse it only after building the model)."""
    from fricenv_agents.config import load_hyperparams, split_hyperparams
    from fricenv_agents.layout import PRETRAINED

    from fricenv.envs import HORIZONS

    path = PRETRAINED.parent / "hyperparams" / "ppo_short.yml"
    for scene in G.SCENES:
        spec = split_hyperparams("ppo", load_hyperparams("ppo", scene, path))
        steps = spec.env_kwargs["max_episode_steps"]
        assert 0 < steps < HORIZONS[scene]
        if spec.warm_start is not None:
            assert spec.warm_start["steps"] <= steps


def test_the_published_page_is_what_the_shipped_runs_episodes_give(tmp_path: Path) -> None:
    """From the shipped episodes, no model loaded: the page is the published one, and
    every shipped run's episodes are the benchmark's 50 nominal plants."""
    (tmp_path / G.CSV_NAME).write_bytes((RESULTS / G.CSV_NAME).read_bytes())
    page = G.main(["--out", str(tmp_path)])
    assert page.read_text() == (RESULTS / "mpc_gap.md").read_text()
    rows = read_episodes(RESULTS / G.CSV_NAME)
    for scene in G.SCENES:
        runs = G.scene_runs(G.DEFAULT_RUNS, scene)
        assert len(runs) == 5
        for run in runs:
            seeds = [r["plant_seed"] for r in rows
                     if r["scene"] == scene and r["training_run"] == run.name]
            assert sorted(seeds) == sorted(eval_seeds(10, 5)), run


def test_the_shipped_runs_trained_with_the_published_recipe() -> None:
    """Each shipped run's config records the entry of ``ppo_short.yml`` for its scene."""
    from fricenv_agents.config import load_hyperparams
    from fricenv_agents.layout import PRETRAINED

    path = PRETRAINED.parent / "hyperparams" / "ppo_short.yml"
    for scene in G.SCENES:
        entry = load_hyperparams("ppo", scene, path)
        for run in G.scene_runs(G.DEFAULT_RUNS, scene):
            cfg = yaml.safe_load((run / "config.yml").read_text())
            assert cfg["hyperparams_file"] == "agents/hyperparams/ppo_short.yml"
            assert cfg["env_kwargs"] == entry["env_kwargs"]
            assert cfg["timesteps_done"] >= entry["n_timesteps"]
            assert ("warm_start" in cfg) == ("warm_start" in entry)
