"""The benchmarks' verdict: a failed bound is named with its measurement and the load."""

from __future__ import annotations

import pytest

from fricenv.bench import env as bench_env
from fricenv.bench import machine_load, verdict
from fricenv.bench import solvers as bench_solvers
from fricenv.bench.solvers import Row


def test_a_failed_bound_is_named_with_the_measurement_and_the_load(capsys):
    line = "bound 2 (single / vector >= 20), fricenv/StickSlip-v0: measured 14.31"
    assert verdict([line], report_only=False) == 1
    out = capsys.readouterr().out
    assert out.startswith("FAIL: these bounds do not hold, with the machine at load average ")
    assert f"  - {line}" in out and "--report-only" in out


def test_report_only_reports_the_same_and_exits_0(capsys):
    line = "bound 1 (single / Pendulum <= 1.0), fricenv/StickSlip-v0: measured 1.07"
    assert verdict([line], report_only=True) == 0
    out = capsys.readouterr().out
    assert out.startswith("NOT JUDGED (--report-only)") and line in out
    assert verdict([], report_only=False) == 0
    assert capsys.readouterr().out.startswith("PASS: every bound holds (load average")


def test_machine_load_reads_the_load_average(monkeypatch):
    monkeypatch.setattr("os.getloadavg", lambda: (3.125, 2.5, 1.0))
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert machine_load() == "load average 3.12, 2.50, 1.00 over 1, 5, 15 min on 2 cores"


def test_the_solvers_bounds_say_which_case_missed_by_how_much():
    rows = [Row("fig4a", "rk4 dt=0.04", 0.87, 1.0, 1.0),
            Row("fig4a", "exact", 1e-13, 0.7, 0.7),  # 0.7x: over the 0.5x bound
            Row("fig4a", "event rtol=1e-10", 1e-11, 0.5, 0.5),
            Row("fig5a", "rk4 dt=0.04", 0.5, 1.0, 1.0),
            Row("fig5a", "exact", 1e-13, 0.3, 0.3),
            Row("fig5a", "event rtol=1e-10", 1e-6, 0.5, 0.5)]  # too inaccurate
    _, failures = bench_solvers._targets(rows)
    assert failures == [
        "exact: error <= 1e-10 at <= 0.5x rk4(0.04) time, case fig4a: measured 0.70x "
        "(exact, error 1.0e-13)",
        "event: error <= 1e-08 at <= 1.0x rk4(0.04) time, case fig5a: no setting reaches "
        "the error (best 1.0e-06)"]


@pytest.mark.parametrize("module", [bench_solvers, bench_env])
def test_the_benchmarks_take_report_only(module):
    assert module.build_parser("b").parse_args(["--report-only"]).report_only
    assert "--report-only" in module.build_parser("b").format_help()
