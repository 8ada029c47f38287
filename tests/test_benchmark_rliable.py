"""The benchmark's returns in rliable's ``(runs x tasks)`` form: the shipped matrices are
what the shipped per-episode CSV gives, and each task's column pools as the page's IQM."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fricenv_agents import statistics as S
from fricenv_agents.benchmark_records import cell_of, read_episodes, rliable_scores, write_rliable

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"


@pytest.fixture(scope="module")
def rows() -> list[dict]:
    return read_episodes(RESULTS / "control_benchmark_episodes.csv")


def test_the_shipped_matrices_are_the_shipped_episodes(rows: list[dict],
                                                       tmp_path: Path) -> None:
    keys = write_rliable(rows, tmp_path / "m.npz")
    made, shipped = np.load(tmp_path / "m.npz"), np.load(RESULTS / "control_benchmark_rliable.npz")
    assert sorted(shipped.files) == sorted(made.files) == sorted([*keys, "tasks"])
    for k in made.files:
        np.testing.assert_array_equal(made[k], shipped[k])
    assert list(shipped["tasks"]) == ["paper", "self_excited", "stribeck", "viscous"]


def test_each_column_pools_as_the_page_iqm(rows: list[dict]) -> None:
    from scipy.stats import trim_mean

    tasks, mats = rliable_scores(rows, "nominal")
    assert mats["ppo"].shape == (5 * 50, len(tasks)) and mats["mpc"].shape == (50, len(tasks))
    for t, scene in enumerate(tasks):
        cell = cell_of(rows, scene, "nominal", "ppo")
        assert trim_mean(mats["ppo"][:, t], 0.25) == pytest.approx(S.iqm(cell), rel=1e-12)


def test_a_missing_cell_or_metric_is_named(rows: list[dict]) -> None:
    with pytest.raises(ValueError, match="no episodes of 'mpc_filter'"):
        cell_of(rows, "paper", "nominal", "mpc_filter")
    with pytest.raises(ValueError, match="unknown metric"):
        cell_of(rows, "paper", "nominal", "mpc", "reward")
