"""Figures are written, with labelled axes and a legend entry for every regime."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.figure import Figure

import fricenv
from fricenv import plotting
from fricenv.params import OscillatorParams
from fricenv.regimes import Regime
from fricenv.sweep import regime_map


def _labelled(ax, which: str) -> bool:
    """Whether the axis ``which`` of ``ax`` is labelled, there or on an axes sharing it
    (stacked panels label their shared time axis once, under the bottom one)."""
    group = ax.get_shared_x_axes() if which == "x" else ax.get_shared_y_axes()
    return any(getattr(a, f"get_{which}label")().strip() for a in group.get_siblings(ax))


def _check_written(fig: Figure, path: Path) -> None:
    for ax in fig.axes:
        if ax.get_visible() and ax.has_data():
            assert _labelled(ax, "x"), "x axis without label"
            assert _labelled(ax, "y"), "y axis without label"
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
    assert len(fig.axes) == len(fricenv.FRICTION_LAWS)  # the paper's three and the exponential law
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
        # --docs the same folder as --out: the copy is skipped (was shutil.SameFileError
        # after all the maps, and no report)
        assert main(["--only", "8-10", "--resolution", "2", "--out", str(tmp_path),
                     "--docs", str(tmp_path), "--no-progress"]) == 0
    assert (tmp_path / "fig10_regime_maps.png").exists()
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


# -- argument checks (review 18: D3, D4, D8, maps figure) ----------------------------------
@pytest.mark.parametrize(
    ("setup", "argv", "needle"),
    [("report.md/", ["--only", "2"], "--out '{out}/report.md' is a folder"),
     ("maps", ["--only", "8-10"], "--out '{out}/maps': '{out}/maps' exists and is not a"),
     ("fig2_friction_laws.png/", ["--only", "2"], "fig2_friction_laws.png' is a folder"),
     ("maps/fig8_coulomb_eta0.11111_2x2.npz/", ["--only", "8-10", "--resolution", "2"],
      "fig8_coulomb_eta0.11111_2x2.npz' is a folder"),
     ("docs/fig9_regime_maps.png/", ["--only", "8-10", "--docs", "{out}/docs"],
      "--docs '{out}/docs/fig9_regime_maps.png' is a folder"),
     (None, ["--only", "2,3x"], "--only: unknown parts ['3x']")],
)
def test_reproduce_cli_checks_the_files_in_its_folders(setup, argv, needle, capsys,
                                                       tmp_path) -> None:
    """These failed only after the work (IsADirectoryError at the end, FileExistsError after
    the first map chunk), leaving no report."""
    from fricenv.reproduce import main

    out = tmp_path / "o"
    if setup:
        (out / setup).parent.mkdir(parents=True, exist_ok=True)
        (out / setup).mkdir() if setup.endswith("/") else (out / setup).write_text("")
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(SystemExit) as e:
        main([*(a.format(out=out) for a in argv), "--out", str(out), "--no-progress"])
    assert e.value.code == 2 and needle.format(out=out) in capsys.readouterr().err
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.parametrize(
    ("kwargs", "exc", "needle"),
    [(dict(out=5), TypeError, "out must be a str or os.PathLike"),
     (dict(docs=5, only=("8-10",)), TypeError, "docs must be a str or os.PathLike"),
     (dict(n_threads=0), ValueError, "n_threads must be in [1, "),
     (dict(n_threads=1.0), TypeError, "n_threads must be an integer"),
     (dict(resolution=0), ValueError, "resolution must be 2 to 1000 cells per axis, got 0"),
     (dict(resolution=2.5), TypeError, "resolution must be an integer, got 2.5"),
     (dict(quick="no"), TypeError, "quick must be a bool"),
     (dict(progress="no"), TypeError, "progress must be a bool"),
     (dict(only="2,3x"), TypeError, "only must be a list of part names"),
     (dict(only=("2", 3)), TypeError, "only must be a list of part names"),
     (dict(only=("x",)), ValueError, "only: unknown parts ['x']"),
     (dict(only=()), ValueError, "only is empty"),
     (dict(out="{tmp}/afile"), ValueError, "out '{tmp}/afile': '{tmp}/afile' exists"),
     (dict(docs="{tmp}/afile", only=("8-10",)), ValueError, "docs '{tmp}/afile'")],
)
def test_reproduce_run_checks_its_arguments_first(kwargs, exc, needle, tmp_path) -> None:
    """reproduce.run validated nothing: errors came after fig2 or all the maps were written,
    quick='no' ran as quick, only='2,3x' ran parts 2 and 3 (substring test) and only=('x',)
    wrote an empty report. Now nothing is computed or written."""
    from fricenv.reproduce import run

    (tmp_path / "afile").write_text("")
    args = dict(out=tmp_path / "r", only=("2",), progress=False)
    args.update({k: v.format(tmp=tmp_path) if isinstance(v, str) and k != "only" else v
                 for k, v in kwargs.items()})
    with pytest.raises(exc, match=re.escape(needle.format(tmp=tmp_path))):
        run(**args)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_reproduce_run_takes_a_str_folder(tmp_path) -> None:
    """run('folder') raised AttributeError: 'str' object has no attribute 'mkdir'."""
    from fricenv.reproduce import run

    path = run(str(tmp_path / "r"), only=["2"], progress=False)
    assert path == tmp_path / "r" / "report.md" and path.exists()
    assert (tmp_path / "r" / "fig2_friction_laws.png").exists()


def test_save_returns_the_file_it_wrote(tmp_path) -> None:
    """Without a suffix save returned 'x' but wrote 'x.png'; the figure stays usable."""
    fig = plotting.friction_laws_figure()
    out = plotting.save(fig, tmp_path / "sub" / "x")
    assert out == tmp_path / "sub" / "x.png" and out.exists()
    out = plotting.save(fig, str(tmp_path / "y.svg"), dpi=72.5)
    assert out == tmp_path / "y.svg" and out.read_text().lstrip().startswith("<?xml")
    assert plotting.save(fig, tmp_path / "z.PDF").read_bytes()[:4] == b"%PDF"


@pytest.mark.parametrize(
    ("fig", "path", "dpi", "exc", "needle"),
    [("fig", "{tmp}/d", 130, ValueError, "path must name a file, got the folder"),
     ("fig", "{tmp}/new/x.foo", 130, ValueError, "unknown image format 'foo'"),
     ("fig", "{tmp}/new/x.png", "high", TypeError, "dpi must be a real number"),
     ("fig", "{tmp}/new/x.png", 0, ValueError, "dpi must be > 0"),
     ("fig", "{tmp}/new/x.png", 10**5, ValueError, "dpi must be > 0 and give at most"),
     ("fig", "{tmp}/new/x.png", float("nan"), ValueError, "dpi must be finite"),
     ("fig", "{tmp}/new/x.png", True, TypeError, "dpi must be a real number"),
     (None, "{tmp}/new/x.png", 130, TypeError, "fig must be a matplotlib Figure"),
     ("fig", 5, 130, TypeError, "path must be a str or os.PathLike"),
     ("fig", b"x.png", 130, TypeError, "path must be a str or os.PathLike"),
     ("fig", "{tmp}/afile/x.png", 130, ValueError, "path '{tmp}/afile': '{tmp}/afile'")],
)
def test_save_checks_before_making_folders(fig, path, dpi, exc, needle, tmp_path) -> None:
    """These failed after mkdir (an empty folder left), in pathlib naming nothing, wrote
    d.png beside a folder d, or ran out of memory (dpi = 1e5)."""
    (tmp_path / "d").mkdir()
    (tmp_path / "afile").write_text("")
    fig = plotting.friction_laws_figure() if fig else fig
    path = path.format(tmp=tmp_path) if isinstance(path, str) else path
    with pytest.raises(exc, match=re.escape(needle.format(tmp=tmp_path))):
        plotting.save(fig, path, dpi=dpi)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "d"]
    assert not any((tmp_path / "d").iterdir())


def _toy_map(u0: np.ndarray, nu: np.ndarray) -> SimpleNamespace:
    """A map-like object: stick in a band that moves with nu, periodic at integer nu."""
    uu, nn = np.meshgrid(u0, nu, indexing="ij")
    labels = np.where((uu > 1 / (1 + nn)) & (uu < 4 * (1 + nn)), Regime.SSM1, Regime.WM1)
    labels = np.where(np.isclose(nn, np.round(nn)) & (labels == Regime.WM1),
                      Regime.PERIODIC_OSCILLATION, labels)
    return SimpleNamespace(u0=u0, nu=nu, labels=labels.astype(np.int8))


def _drawn(m: object) -> tuple:
    fig = plotting.regime_maps_figure([m])
    ax = fig.axes[0]
    return (np.asarray(ax.collections[0].get_array()).tolist(), ax.get_xscale(),
            [ln.get_xydata().tolist() for ln in ax.lines])


def test_unsorted_grid_is_drawn_as_the_sorted_one() -> None:
    """Unsorted axes were drawn with meaningless cell edges and boundary lines."""
    u0, nu = np.geomspace(0.1, 50, 9), np.linspace(0.25, 3.0, 12)
    rng = np.random.default_rng(0)
    iu, jn = rng.permutation(u0.size), rng.permutation(nu.size)
    m = _toy_map(u0, nu)
    shuffled = SimpleNamespace(u0=u0[iu], nu=nu[jn], labels=m.labels[np.ix_(iu, jn)])
    assert _drawn(shuffled) == _drawn(m)
    assert _drawn(m)[1] == "log"
    for axis in ("u0", "nu"):
        dup = _toy_map(u0, nu)
        setattr(dup, axis, np.sort(np.r_[getattr(dup, axis)[:-1], getattr(dup, axis)[0]]))
        with pytest.raises(ValueError, match=f"rmap.{axis} must not repeat a value"):
            plotting.regime_maps_figure([dup])
    bad = _toy_map(u0, nu)
    bad.labels = bad.labels[:, :-1]
    with pytest.raises(ValueError, match="rmap.labels must have shape"):
        plotting.regime_maps_figure([bad])


def test_regime_maps_figure_checks_maps_and_titles() -> None:
    """A short titles list gave IndexError and maps=[] a matplotlib error; five maps give
    a 3 x 2 grid, as the docstring now says (two per row)."""
    m = _toy_map(np.geomspace(0.1, 50, 4), np.linspace(0.5, 2.0, 4))
    with pytest.raises(ValueError, match=re.escape("titles must have one entry per map (2)")):
        plotting.regime_maps_figure([m, m], ["(a)"])
    with pytest.raises(ValueError, match="titles must have one entry per map"):
        plotting.regime_maps_figure([m], [])
    with pytest.raises(TypeError, match="titles must be a list of str"):
        plotting.regime_maps_figure([m, m], "ab")
    with pytest.raises(ValueError, match="maps is empty"):
        plotting.regime_maps_figure([])
    with pytest.raises(TypeError, match="maps must be a list of RegimeMap"):
        plotting.regime_maps_figure(m)
    with pytest.raises(TypeError, match="rmap must be a RegimeMap"):
        plotting.regime_maps_figure([5])
    fig = plotting.regime_maps_figure([m] * 5, [f"({k})" for k in "abcde"])
    assert len([ax for ax in fig.axes if ax.get_visible()]) == 5 and len(fig.axes) == 6


def test_docs_plane_example_draws_its_map(tmp_path, monkeypatch) -> None:
    """The (u0, eta) example of docs/regimes.md (``cell_statistics`` + the regime colours) runs as
    printed and finds the three regimes its plane holds."""
    import matplotlib

    matplotlib.use("Agg")
    text = (Path(__file__).parents[1] / "docs" / "regimes.md").read_text(encoding="utf-8")
    section = text.split("## Other parameter planes", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(code, "docs/regimes.md", "exec"), ns)
    assert (tmp_path / "coulomb_u0_eta.png").stat().st_size > 5_000
    assert set(np.unique(ns["labels"]).tolist()) == {Regime.WM1, Regime.WM2, Regime.SSM1}
    assert ns["labels"].shape == ns["stick_fraction"].shape == (60, 60)
    assert not np.any(ns["status"])
    import matplotlib.pyplot as plt

    plt.close(ns["fig"])


def test_legend_handles_without_the_boundary_lines() -> None:
    patches = plotting.regime_legend_handles(boundaries=False)
    assert [h.get_label() for h in patches] == [plotting.REGIME_SHORT[r] for r in Regime]
    assert len(plotting.regime_legend_handles()) == len(patches) + 2


def test_every_regime_is_drawn_in_its_own_colour() -> None:
    from matplotlib.colors import to_hex

    cmap, norm = plotting.regime_cmap()
    assert to_hex(cmap(norm(-1))) == "#ffffff"  # not computed
    for r in Regime:
        assert to_hex(cmap(norm(int(r)))) == plotting.REGIME_COLORS[r]
    assert len(set(plotting.REGIME_COLORS.values())) == len(Regime)
    labels = np.array([[int(r) for r in Regime]], dtype=np.int8)
    m = SimpleNamespace(u0=np.array([1.0]), nu=0.1 + 0.2 * np.arange(len(Regime)),
                        labels=labels)
    assert np.ravel(_drawn(m)[0]).tolist() == [float(r) for r in Regime]
