"""Every figure fricenv draws can be read alone: a title, axis labels with their unit
("dimensionless" in this model), a legend where colours carry meaning, and one time
label under stacked panels. Regime maps read the same wherever they are drawn."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.colors import to_hex
from matplotlib.figure import Figure

import fricenv
from fricenv import plotting
from fricenv.atlas import regime_map_dataset
from fricenv.params import OscillatorParams
from fricenv.sweep import regime_map


def _title(fig: Figure) -> str:
    sup = fig._suptitle.get_text() if fig._suptitle is not None else ""
    return sup or " ".join(ax.get_title() for ax in fig.axes if ax.get_visible())


def _check_labels(fig: Figure) -> None:
    """Each drawn axes' x and y labels name a unit, on it or on an axes sharing it."""
    for ax in fig.axes:
        if not (ax.get_visible() and ax.has_data()):
            continue
        for which, group in (("x", ax.get_shared_x_axes()), ("y", ax.get_shared_y_axes())):
            labels = [getattr(a, f"get_{which}label")() for a in group.get_siblings(ax)]
            assert any("(dimensionless" in t for t in labels), (which, labels)


def _legend_entries(ax: Axes) -> dict[str, str]:
    """legend text -> face colour of its patch (regime entries) or '' (lines)."""
    legend = ax.get_legend()
    assert legend is not None, "no legend"
    out = {}
    for text, handle in zip(legend.get_texts(), legend.legend_handles, strict=True):
        face = handle.get_facecolor() if hasattr(handle, "get_facecolor") else None
        out[text.get_text()] = "" if face is None else to_hex(face)
    return out


@pytest.fixture(scope="module")
def small_map():
    return regime_map(OscillatorParams.preset("coulomb", eta=0.6), np.geomspace(0.2, 40, 10),
                      np.linspace(0.2, 3.0, 15), progress=False)


def test_fig2_and_fig3_have_titles_labels_and_legends() -> None:
    from fricenv.reproduce import linear_amplitude

    fig = plotting.friction_laws_figure()
    assert _title(fig).startswith("Fig. 2")
    assert fig.axes[0].get_legend() is not None
    _check_labels(fig)
    eta = np.linspace(0.1, 3, 40)
    pan = dict(lam=0.5, nu=2.5, eta=eta, curves={u: linear_amplitude(eta, 2.5, 0.5, u)
                                                 for u in (0.1, 0.2)})
    fig = plotting.amplitude_figure([pan, pan])
    assert fig._suptitle is not None and fig._suptitle.get_text().startswith("Fig. 3")
    assert len(_legend_entries(fig.axes[0])) >= 2  # colours: one u0 each
    _check_labels(fig)


def test_stacked_time_histories_label_time_once() -> None:
    t = np.linspace(0, 20, 201)
    run = dict(t=t, x=np.sin(t), v=np.cos(t), mode=np.where(np.cos(t) > 0.9, 0, -1), V=1.0)
    fig = plotting.time_history_figure([run, run])
    top, bottom = fig.axes[0], fig.axes[2]  # (column 1: x above v)
    assert top.get_xlabel() == "" and "time τ (dimensionless)" == bottom.get_xlabel()
    assert all(ax.get_title() for ax in fig.axes[:2])  # each column names its run
    assert "stick" in _legend_entries(bottom)
    _check_labels(fig)


def test_trajectory_plot_labels_its_axes() -> None:
    tr = fricenv.simulate(OscillatorParams.preset("coulomb", eta=0.6, nu=0.5, u0=1.0), 20.0)
    for y in ("x", "v"):
        ax = Figure().add_subplot()
        tr.plot(ax, y=y)
        assert ax.get_title() and "(dimensionless)" in ax.get_xlabel()
        assert "(dimensionless)" in ax.get_ylabel()


def test_regime_map_plot_and_plot_slice_read_the_same(small_map) -> None:
    """RegimeMap.plot and fricenv.atlas.plot_slice draw the same colours with the same
    legend: one entry per regime present, then the boundary lines."""
    ax_map = small_map.plot(Figure().add_subplot())
    ax_slice = fricenv.atlas.plot_slice(regime_map_dataset(small_map), Figure().add_subplot())
    for ax in (ax_map, ax_slice):
        assert ax.get_title().startswith("Coulomb law")
        assert "(dimensionless" in ax.get_xlabel() and "(dimensionless" in ax.get_ylabel()
    entries = _legend_entries(ax_map)
    assert entries == _legend_entries(ax_slice)
    present = {plotting.REGIME_SHORT[plotting.Regime(v)]: to_hex(plotting.REGIME_COLORS[
        plotting.Regime(v)]) for v in np.unique(small_map.labels)}
    assert {k: v for k, v in entries.items() if v} == present
    assert "1st boundary: stick begins" in entries
    assert np.array_equal(ax_map.collections[0].get_array(),
                          ax_slice.collections[0].get_array())


def test_atlas_figures_have_titles(small_map) -> None:
    ds = regime_map_dataset(small_map)
    fig = fricenv.atlas.slice_figure(ds)
    assert _title(fig).startswith("Coulomb law: regimes over (u0, nu)") and fig.legends
    _check_labels(fig)
    ax = fricenv.atlas.plot_slice(ds, Figure().add_subplot(), x="nu", y="u0")
    assert ax.get_title() and ax.get_legend() is not None
    fig = plotting.regime_maps_figure([small_map])
    assert fig.axes[0].get_title() == "Coulomb law, η = 0.6" and fig.legends
    _check_labels(fig)
