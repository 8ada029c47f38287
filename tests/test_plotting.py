"""Figures are written, with labelled axes and a legend entry for every regime."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from fricenv import plotting
from fricenv.params import OscillatorParams
from fricenv.regimes import Regime
from fricenv.sweep import regime_map


def _check_written(fig: Figure, path: Path) -> None:
    for ax in fig.axes:
        if ax.get_visible() and ax.has_data():
            assert ax.get_xlabel().strip(), "x axis without label"
            assert ax.get_ylabel().strip(), "y axis without label"
    out = plotting.save(fig, path)
    assert out.exists() and out.stat().st_size > 5_000
    with open(out, "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n"


def test_core_does_not_import_plotting() -> None:
    import subprocess

    code = ("import sys, fricenv, fricenv.sweep, fricenv.regimes, fricenv.core; "
            "print('matplotlib' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_friction_laws_figure(tmp_path) -> None:
    fig = plotting.friction_laws_figure()
    assert len(fig.axes) == 3
    _check_written(fig, tmp_path / "fig2.png")


def test_amplitude_figure(tmp_path) -> None:
    from fricenv.reproduce import linear_amplitude

    eta = np.linspace(0.1, 3, 50)
    pan = dict(lam=0.5, nu=2.5, eta=eta, curves={0.1: linear_amplitude(eta, 2.5, 0.5, 0.1)},
               sim={0.1: (eta[::10], linear_amplitude(eta[::10], 2.5, 0.5, 0.1),
                          np.arange(5) > 2)})
    fig = plotting.amplitude_figure([pan, pan])
    _check_written(fig, tmp_path / "fig3.png")


def test_linear_amplitude_matches_closed_form() -> None:
    from fricenv.reproduce import linear_amplitude

    eta = np.array([0.3, 0.9, 1.7])
    a1 = 0.2 / np.sqrt((1 - eta**2) ** 2 + (0.5 * eta) ** 2)
    a2 = 0.2 / np.sqrt((1 - (np.sqrt(2) * eta) ** 2) ** 2 + (0.5 * np.sqrt(2) * eta) ** 2)
    # incommensurate: the envelope maximum A1 + A2
    np.testing.assert_allclose(linear_amplitude(eta, np.sqrt(2), 0.5, 0.2), a1 + a2)
    # nu = 1: one tone of amplitude 2 u0
    np.testing.assert_allclose(linear_amplitude(eta, 1.0, 0.5, 0.2), 2 * a1, rtol=1e-4)


def test_time_history_figure(tmp_path) -> None:
    t = np.linspace(0, 50, 501)
    run = dict(t=t, x=np.sin(t), v=np.cos(t), mode=np.where(np.cos(t) > 0.9, 0, -1), V=1.0,
               title="test")
    fig = plotting.time_history_figure([run, run], suptitle="Fig. x")
    assert len(fig.axes) == 4
    _check_written(fig, tmp_path / "fig4.png")


@pytest.fixture(scope="module")
def small_maps() -> list:
    nu = np.linspace(0.1, 4.0, 40)  # integers on the grid
    u0 = np.geomspace(0.2, 40, 12)
    return [regime_map(OscillatorParams.preset("coulomb", eta=eta), u0, nu, progress=False)
            for eta in (0.6, 7 / 3)]


def test_regime_maps_figure(tmp_path, small_maps: list) -> None:
    fig = plotting.regime_maps_figure(small_maps, ["(a)", "(b)"], suptitle="maps")
    legend_texts = {t.get_text() for lg in fig.legends for t in lg.get_texts()}
    for r in Regime:
        assert plotting.REGIME_SHORT[r] in legend_texts
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2
    assert all(ax.get_xscale() == "log" for ax in axes)  # geometric u0 grid
    assert "u_0" in axes[0].get_xlabel() and "ν" in axes[0].get_ylabel()
    # both regime boundaries are drawn (solid: stick begins, dashed: last stick)
    for ax in axes:
        styles = {ln.get_linestyle() for ln in ax.lines if ln.get_color() == "k"}
        assert {"-", "--"} <= styles
    _check_written(fig, tmp_path / "fig8.png")


def test_partial_map_can_be_drawn(tmp_path, small_maps: list) -> None:
    m = small_maps[0]
    m.labels = m.labels.copy()
    m.done = m.done.copy()
    m.labels[5:] = -1
    m.done[5:] = False
    fig = plotting.regime_maps_figure([m])
    _check_written(fig, tmp_path / "partial.png")


def test_reproduce_cli_small_parts(tmp_path) -> None:
    from fricenv.reproduce import main

    assert main(["--only", "2,4-7", "--out", str(tmp_path), "--no-progress"]) == 0
    for name in ("fig2_friction_laws.png", "fig4_time_history.png", "fig7_time_history.png",
                 "report.md"):
        assert (tmp_path / name).exists(), name
    text = (tmp_path / "report.md").read_text()
    assert "Fig. 7" in text and "PERIODIC_OSCILLATION" in text
    with pytest.raises(SystemExit):
        main(["--only", "11"])


def test_reproduce_coarse_maps_judge_nothing_they_cannot(tmp_path) -> None:
    """2 x 2 cells per panel leave the report's selections (0.2 < nu < 0.8, non-integer nu,
    ...) empty: those observations must read "n/a", not "differ", and warn about nothing."""
    import warnings

    from fricenv.reproduce import main

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["--only", "8-10", "--resolution", "2", "--out", str(tmp_path),
                     "--no-progress"]) == 0
    rows = [r for r in (tmp_path / "report.md").read_text().splitlines()
            if r.startswith("| Fig")]
    verdicts = [r.rsplit("|", 2)[1].strip() for r in rows]
    assert verdicts.count("n/a") >= 10, verdicts
    assert "differ" not in verdicts, verdicts


@pytest.mark.parametrize(
    ("argv", "needle"),
    [(["--resolution", "0"], "--resolution"), (["--threads", "0"], "--threads"),
     (["--threads", "100000"], "--threads")],
)
def test_reproduce_cli_rejects_bad_numbers(argv, needle, capsys, tmp_path) -> None:
    from fricenv.reproduce import main

    with pytest.raises(SystemExit):
        main([*argv, "--out", str(tmp_path)])
    assert needle in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # refused before anything is computed or written


@pytest.mark.parametrize(
    ("argv", "needle"),
    [(["--resolution", "100000"], "--resolution must be 2 to 1000"),
     (["--out", "{file}"], "--out"), (["--out", "{file}/sub"], "--out"),
     (["--out", "{tmp}/rp", "--docs", "{file}"], "--docs")],
)
def test_reproduce_cli_checks_its_folders_first(argv, needle, capsys, tmp_path) -> None:
    """A late FileExistsError (after minutes of maps) left half a report behind."""
    from fricenv.reproduce import main

    (tmp_path / "afile").write_text("")
    argv = [a.format(file=tmp_path / "afile", tmp=tmp_path) for a in argv]
    with pytest.raises(SystemExit) as e:
        main(["--only", "8-10", *argv])
    assert e.value.code == 2 and needle in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.parametrize(
    ("script", "argv", "needle"),
    [("paper_cases.py", ["--t-end", "-5", "--out", "{tmp}/pc"], "--t-end"),
     ("paper_cases.py", ["--t-end", "nan", "--out", "{tmp}/pc"], "--t-end"),
     ("paper_cases.py", ["--out", "{file}"], "--out"),
     ("bench_sweep.py", ["--json", "{tmp}"], "--json"),
     ("bench_env.py", ["--json", "{tmp}"], "--json"),
     ("bench_solvers.py", ["--out", "{file}"], "--out")],
)
def test_scripts_check_arguments_before_working(script, argv, needle, tmp_path) -> None:
    """Each refuses a bad option at once (exit 2, naming it), writing nothing; the benchmarks
    used to find an unusable output path only after minutes of measuring."""
    import subprocess
    import sys
    from pathlib import Path

    (tmp_path / "afile").write_text("")
    argv = [a.format(file=tmp_path / "afile", tmp=tmp_path) for a in argv]
    path = Path(__file__).resolve().parents[1] / "scripts" / script
    r = subprocess.run([sys.executable, str(path), *argv], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and needle in r.stderr, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.slow
def test_reproduce_quick_end_to_end(tmp_path) -> None:
    from fricenv.reproduce import main

    assert main(["--quick", "--out", str(tmp_path), "--no-progress"]) == 0
    for k in (2, 3, 8, 9, 10):
        assert list(tmp_path.glob(f"fig{k}_*.png")), k
    assert "| verdict |" in (tmp_path / "report.md").read_text()
