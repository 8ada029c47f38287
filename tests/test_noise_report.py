"""Noise and delay in returns as well as retention: the report recomputes the benchmark's
own retentions from its CSV, and the shipped page is what the shipped CSV gives."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fricenv_agents import noise_report as N

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results"


def test_the_report_is_the_shipped_one_and_agrees_with_the_benchmark(tmp_path: Path) -> None:
    page = N.main(["--csv", str(RESULTS / "control_benchmark_episodes.csv"),
                   "--out", str(tmp_path)])
    assert page.read_text() == (RESULTS / "noise_report.md").read_text()
    rep = json.loads((tmp_path / "noise_report.json").read_text())
    bench = json.loads((RESULTS / "control_benchmark.json").read_text())["cuts_and_retentions"]
    for scene, per in rep.items():
        for key, r in per.items():
            own = bench[scene][key]["retention, noise + delay"]["estimate"]
            assert r["retention_own"]["estimate"] == pytest.approx(own, rel=1e-9)
        # the nominal PPO against its own in-range cut: the two retentions coincide
        assert per["ppo"]["retention_own"] == per["ppo"]["retention_of_ppo"]
        for r in per.values():
            assert r["return_change"]["lo"] <= r["return_change"]["estimate"] \
                <= r["return_change"]["hi"]
