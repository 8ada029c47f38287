"""The identification benchmark's page counts selection on the records that single out a
law apart from the records of two laws at once (scripts/identification_page.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
page = pytest.importorskip("identification_page")


def _row(law, best, tie, sides, exc="default", periods=20, seconds=2.0, trial=0):
    return {"law": law, "best": best, "tie": tuple(tie.split("|")),
            "true_sides": tuple(int(s) for s in sides.split("|")), "excitation": exc,
            "snr_db": 30.0, "periods": periods, "param": "lam", "trial": trial,
            "seconds": seconds}


def test_ties_count_apart_and_only_where_the_record_is_two_laws():
    rows = [
        _row("viscous", "coulomb", "coulomb|viscous", "-1"),      # tie named: right
        _row("coulomb", "coulomb", "coulomb", "-1"),              # one law claimed
        _row("viscous", "coulomb", "coulomb", "-1|1", "designed"),  # wrong: it could tell
        _row("stribeck", "stribeck", "stribeck", "-1"),           # right
        _row("stribeck", "stribeck", "stribeck", "-1", trial=1),  # right
    ]
    assert [page.indistinguishable(r) for r in rows] == [True, True, False, False, False]
    table, share = page.selection(rows)
    assert share[(30.0, "default")] == (2, 2, 1, 2)
    assert share[(30.0, "designed")] == (0, 1, 0, 0)
    assert "| 30 dB | default | 2 | 2 (100.0 %) | 2 | 1 (50.0 %) | 1 |" in table


def test_projection_scales_the_measured_cost_to_the_full_grid():
    rows = [_row("coulomb", "coulomb", "coulomb", "-1", exc, periods, seconds=3.0)
            for periods in page.PERIODS for exc in page.EXCITATIONS]
    text = page.projection(rows)
    # 72 cells x 200 trials x 3 s
    assert f"{72 * 200 * 3.0 / 3600:.0f} hours" in text and "no records yet" not in text
    assert "no records yet of 50 periods designed" in page.projection(rows[:-1])
