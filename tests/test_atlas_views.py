"""Views of an atlas (slices, stick boundaries, the onset surface) and its command line."""

from __future__ import annotations

import numpy as np
import pytest

import fricenv
from fricenv.cli.atlas import module_main as cli_main
from fricenv.cli.atlas import parse_axis
from fricenv.regimes import Regime


def _run(*args, **kw):
    return fricenv.atlas(*args, progress=False, **kw)


def test_stick_boundaries_and_views():
    u0 = np.geomspace(0.2, 60.0, 24)
    ds = _run("coulomb", {"u0": u0, "nu": np.array([0.3, 1.5]), "eta": np.array([0.2, 0.6])})
    b = fricenv.atlas.stick_boundaries(ds)
    assert b.onset.dims == ("nu", "eta")
    stick = np.isin(ds.label.values, [int(r) for r in Regime if r.has_stick])
    for j in range(2):
        for k in range(2):
            i = np.flatnonzero(stick[:, j, k])
            assert b.onset.values[j, k] == u0[i[0]] and b.last_stick.values[j, k] == u0[i[-1]]
    ax = fricenv.atlas.plot_slice(ds, eta=0.6)
    assert ax.get_xscale() == "log" and "u_0" in ax.get_xlabel()
    fig = fricenv.atlas.onset_surface_figure(ds)
    assert len(fig.axes) == 3
    assert fig.get_suptitle().startswith("Coulomb law: stick onset in u0")
    fig = fricenv.atlas.slice_figure(ds, panel="eta")
    assert len([a for a in fig.axes if a.get_visible()]) == 2
    with pytest.raises(ValueError, match=r"select a value of each other axis: \['eta'\]"):
        fricenv.atlas.plot_slice(ds)


def test_cli_writes_and_resumes(tmp_path, capsys):
    out = tmp_path / "c.zarr"
    argv = ["--law", "stribeck", "--axis", "u0=geom:0.5:20:4", "--axis", "nu=lin:0.5:2:3",
            "--axis", "eta=0.2,0.6", "--out", str(out), "--no-progress", "--chunks", "8"]
    assert cli_main(argv) == 0
    assert f"wrote {out}: 24 cells" in capsys.readouterr().out
    assert cli_main(argv) == 0
    ds = fricenv.open_atlas(out)
    assert dict(ds.sizes) == {"u0": 4, "nu": 3, "eta": 2}
    assert cli_main(argv[:-2] + ["--setting", "window_min=50"]) == 2
    assert "setting window_min = 100.0, not 50.0" in capsys.readouterr().err
    name, grid = parse_axis("u0=geom:0.1:1000:5")
    assert name == "u0" and np.allclose(grid, [0.1, 1, 10, 100, 1000])
    with pytest.raises(ValueError, match="--axis 'nu=lin:1:2'"):
        parse_axis("nu=lin:1:2")
