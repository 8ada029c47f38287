"""The MPC's per-scene settings: where they come from (the search on tuning episodes), how a
controller picks them up, and the comparison against PPO that uses them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fricenv_agents import mpc_compare as C
from fricenv_agents import mpc_tuning as T
from fricenv_agents.benchmark_records import read_episodes
from fricenv_agents.layout import EVAL_SEED_BASE, MAX_PLANTS, SEARCH_SEED_BASE, eval_seeds
from fricenv_agents.mpc import (
    DEFAULT_ITERATIONS,
    SETTINGS,
    TUNE_SEED_BASE,
    TUNED,
    MPPIController,
    scene_settings,
)

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"


def test_the_tuning_episodes_are_no_evaluation_or_search_episode() -> None:
    search = json.loads((RESULTS / "mpc_tuning.json").read_text())
    tuning = set(range(TUNE_SEED_BASE, TUNE_SEED_BASE + search["episodes"]))
    assert search["seed_base"] == TUNE_SEED_BASE
    assert not tuning & set(eval_seeds(10, 5))  # the benchmark's episodes
    assert min(tuning) >= SEARCH_SEED_BASE + MAX_PLANTS  # after the best-constant search
    assert max(tuning) < EVAL_SEED_BASE or min(tuning) >= SEARCH_SEED_BASE


def test_the_defaults_are_the_published_search_picks() -> None:
    """``TUNED`` is what the shipped search picked, and picking again from its rows by
    the published rule gives the same settings."""
    search = json.loads((RESULTS / "mpc_tuning.json").read_text())
    assert set(search["picks"]) == set(TUNED)
    for scene, best in search["picks"].items():
        assert TUNED[scene] == best == T.pick(search["rows"], scene)
        ctrl = MPPIController(scene)
        assert {k: ctrl.describe()[k] for k in SETTINGS} == best


def test_an_explicit_setting_wins_and_an_untuned_scene_gets_the_generic_ones() -> None:
    assert scene_settings("self_excited", iterations=1)["iterations"] == 1
    assert scene_settings("exponential")["iterations"] == DEFAULT_ITERATIONS
    with pytest.raises(ValueError, match="unknown MPPI settings"):
        scene_settings("paper", horizn=3)
    with pytest.raises(ValueError, match="temperature"):
        MPPIController("paper", temperature=-1.0)


def test_the_pick_is_the_best_mean_then_the_cheaper() -> None:
    base = {"scene": "paper", "horizon": 12, "temperature": 0.1, "noise_std": 0.5}
    rows = [{**base, "samples": 512, "iterations": 2, "return_mean": -1.0,
             "intervals_per_decision": 12288},
            {**base, "samples": 256, "iterations": 2, "return_mean": -1.0,
             "intervals_per_decision": 6144},
            {**base, "samples": 256, "iterations": 4, "return_mean": -2.0,
             "intervals_per_decision": 12288}]
    assert T.pick(rows, "paper")["samples"] == 256
    with pytest.raises(ValueError, match="no search rows"):
        T.pick(rows, "viscous")
    assert len(T.coarse_settings()) == 12
    assert len({T.key_of(s) for s in T.coarse_settings()}) == 12


def test_the_comparison_says_where_ppo_leads_and_trails_in_one_sentence() -> None:
    """On the shipped CSVs against the MPC with its earlier generic settings (no compute):
    the statistics are those of the cells, and the sentence names both sides when they
    differ."""
    from fricenv_agents import statistics as S
    from fricenv_agents.benchmark_records import cell_of

    rows = [r for r in read_episodes(C.DEFAULT_CSV) if r["controller"] != "mpc"]
    rows += read_episodes(C.GENERIC_CSV)
    r = C.compare_scene(rows, "paper", ref="mpc")
    ppo, mpc = (cell_of(rows, "paper", "nominal", k) for k in ("ppo", "mpc"))
    assert r["iqm_learned"]["estimate"] == pytest.approx(S.iqm(ppo))
    assert r["mean_ref"]["estimate"] == pytest.approx(mpc.mean())
    assert r["cvar_learned"] == pytest.approx(np.sort(ppo.ravel())[:13].mean())
    assert r["worst_learned"] == ppo.min()
    assert r["win_share"]["estimate"] == pytest.approx(float((ppo > mpc).mean()))
    for name in ("gap_iqm", "gap_mean", "win_share"):
        assert r[name]["lo"] <= r[name]["estimate"] <= r[name]["hi"]
    text = C.sentence("paper", r, "the MPC")
    # on paper the two aggregates disagree: the sentence must carry both
    assert "behind the MPC by the IQM" in text and "ahead of it by the mean" in text


def test_the_comparison_resumes_from_its_csv_without_running(tmp_path: Path) -> None:
    """A scene already in ``--out``'s CSV is not run again: with the benchmark's own MPC
    rows standing in for the rerun, the page is made from the files alone."""
    rows = [dict(r, controller=C.TUNED_KEY) for r in read_episodes(C.DEFAULT_CSV)
            if r["controller"] == "mpc" and r["condition"] == "nominal"
            and r["scene"] == "paper"]
    C._write_csv(tmp_path / C.CSV_NAME, rows)
    C._write_csv(tmp_path / "generic.csv", [dict(r, controller="mpc") for r in rows])
    page = C.main(["--scenes", "paper", "--out", str(tmp_path),
                   "--generic-csv", str(tmp_path / "generic.csv")])
    text = page.read_text()
    assert "| `paper` |" in text and "On `paper` PPO is" in text
    saved = json.loads((tmp_path / "mpc_compare.json").read_text())
    # both stand-ins are the benchmark's MPC: both comparisons agree
    assert saved["tuned"]["paper"]["gap_iqm"] == saved["earlier_settings"]["paper"]["gap_iqm"]
    C.main(["--scenes", "paper", "--out", str(tmp_path),
            "--generic-csv", str(tmp_path / "absent.csv")])
    saved = json.loads((tmp_path / "mpc_compare.json").read_text())
    assert saved["earlier_settings"] == {}  # no file: no reference table
    assert "For reference" not in (tmp_path / "mpc_compare.md").read_text()


def test_the_published_search_page_is_its_json(tmp_path: Path) -> None:
    (tmp_path / "mpc_tuning.json").write_bytes((RESULTS / "mpc_tuning.json").read_bytes())
    T.main(["--out", str(tmp_path), "--page-only"])
    assert (tmp_path / "mpc_tuning.md").read_text() == (RESULTS / "mpc_tuning.md").read_text()


def test_the_published_comparison_is_what_the_shipped_episodes_give(tmp_path: Path) -> None:
    (tmp_path / C.CSV_NAME).write_bytes((RESULTS / C.CSV_NAME).read_bytes())
    page = C.main(["--out", str(tmp_path)])
    assert page.read_text() == (RESULTS / "mpc_compare.md").read_text()
    tuned = read_episodes(RESULTS / C.CSV_NAME)
    assert {r["plant_seed"] for r in tuned} == set(eval_seeds(10, 5))
    assert len(tuned) == 4 * 50
