"""Regime atlases: equal to regime maps bit for bit, locally and on a Dask cluster; Zarr
stores that resume, survive SIGKILL and refuse other atlases; bad input refused before any
cell runs; a bounded client; views and the command line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import zarr
from distributed import Client, LocalCluster

import fricenv
from fricenv import cells
from fricenv.atlas import api, core, distributed, regime_map_dataset, store
from fricenv.params import OscillatorParams
from fricenv.regimes import Regime
from fricenv.sweep import SweepSettings, cell_statistics, regime_map

ROOT = Path(__file__).resolve().parents[1]
U0 = np.geomspace(0.2, 40.0, 7)
NU = np.array([0.25, 0.5, 0.9, 1.0, 1.3, 2.0])
LAWS = ("coulomb", "viscous", "stribeck")
#: Cells of a microsecond: a transient and a window far shorter than any forcing period.
CHEAP = SweepSettings(transient_min=0.0, transient_efolds=0.0, transient_periods=0.0,
                      window_min=0.05, window_periods=0.0, q_max=0)


@pytest.fixture(scope="module")
def client():
    """Two single-threaded, spawn-started workers (as in CI), shared by the module."""
    distributed.warm_kernels()  # compile here first, so the workers only load the cache
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as c:
        yield c


def _env() -> dict:
    """The environment of a subprocess that imports this checkout's fricenv."""
    path = os.environ.get("PYTHONPATH")
    return {**os.environ, "PYTHONPATH": str(ROOT) + (os.pathsep + path if path else "")}


def _run(*args, **kw) -> xr.Dataset:
    return fricenv.atlas(*args, progress=False, **kw)


def test_import_fricenv_loads_no_scale_dependency():
    code = ("import sys, fricenv; bad = [m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed', 'zarr', 'xarray')]; print(bad); "
            "assert not bad; assert callable(fricenv.atlas); "
            "import fricenv.atlas as a; assert fricenv.atlas is a and callable(a); "
            "import fricenv.cli.atlas, fricenv.atlas.core; assert not [m for m in "
            "sys.modules if m.split('.')[0] in ('dask', 'distributed', 'zarr', 'xarray')]; "
            "import inspect; assert 'axes' in inspect.signature(fricenv.atlas).parameters")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT,
                   env=_env())


@pytest.mark.parametrize("law", LAWS)
def test_equals_regime_map_bit_for_bit(law):
    ds = _run(law, {"u0": U0, "nu": NU}, chunks=8)
    ref = regime_map_dataset(regime_map(law, U0, NU, progress=False))
    xr.testing.assert_identical(ds, ref)
    assert set(np.unique(ds.label.values)) > {Regime.WM1, Regime.SSM1}


@pytest.mark.parametrize("law", LAWS)
def test_distributed_equals_local_bit_for_bit(client, law):
    axes = {"u0": U0, "nu": NU, "eta": np.array([0.2, 0.6, 1.667])}
    local = _run(law, axes, chunks=16)
    dist = _run(law, axes, client=client, chunks=16)
    xr.testing.assert_identical(dist, local)
    for k, eta in enumerate(axes["eta"]):  # and each eta slice is that eta's regime map
        ref = regime_map(OscillatorParams.preset(law, eta=eta), U0, NU, progress=False)
        for v in core.VARIABLES:
            np.testing.assert_array_equal(local[v].isel(eta=k).values,
                                          regime_map_dataset(ref)[v].values, err_msg=v)


def _warm_count(dask_worker) -> int:
    plugin = dask_worker.plugins.get(distributed.PLUGIN_NAME)
    return getattr(plugin, "setups", -1)


def test_workers_warm_their_kernels_once(client):
    _run("coulomb", {"u0": U0[:2]}, client=client)
    _run("coulomb", {"u0": U0[:2]}, client=client)
    assert set(client.run(_warm_count).values()) == {1}


def test_other_axes_equal_cell_statistics():
    base = OscillatorParams.preset("viscous", u0=1.5, nu=0.5)
    axes = {"lam": np.array([0.3, 0.5]), "xfk": np.array([1.5, 2.5]),
            "V": np.array([0.5, 1.0]), "xfs": np.array([2.5, 4.0])}
    ds = _run(base, axes, chunks=5)
    grid = [dict(zip(axes, v, strict=True)) for v in
            np.stack(np.meshgrid(*axes.values(), indexing="ij"), -1).reshape(-1, 4)]
    labels, stats, period, status = cell_statistics([base.replace(**g) for g in grid])
    np.testing.assert_array_equal(ds.label.values.ravel(), labels)
    np.testing.assert_array_equal(ds.v_max.values.ravel(), stats[:, 5])
    np.testing.assert_array_equal(ds.status.values.ravel(), status)


def test_friction_law_axis_mixes_methods_like_regime_maps():
    ds = _run("coulomb", {"b1": np.array([0.0, 0.2]), "u0": U0[:4], "nu": NU[:3]})
    for k, b1 in enumerate((0.0, 0.2)):
        ref = regime_map(OscillatorParams(b1=b1), U0[:4], NU[:3], progress=False)
        np.testing.assert_array_equal(ds.v_min.isel(b1=k).values, ref.v_min)
        np.testing.assert_array_equal(ds.label.isel(b1=k).values, ref.labels)


def test_attrs_record_base_settings_algorithm_and_flags():
    settings = SweepSettings(window_min=50.0)
    ds = _run(OscillatorParams.preset("stribeck", lam=0.4), {"nu": NU[:2], "u0": U0[:2]},
              settings=settings)
    assert ds.label.dims == ("nu", "u0")
    assert json.loads(ds.attrs["base"])["lam"] == 0.4
    assert json.loads(ds.attrs["settings"])["window_min"] == 50.0
    assert ds.attrs["algorithm"] == fricenv.sweep.ALGORITHM
    assert ds.label.attrs["flag_meanings"].split() == [r.name for r in Regime]
    assert ds.label.attrs["flag_values"] == [int(r) for r in Regime]


def test_store_streams_and_resumes_only_missing_chunks(tmp_path, monkeypatch):
    path = tmp_path / "a.zarr"
    axes = {"u0": U0, "nu": NU}
    full = _run("coulomb", axes, chunks=(2, 3))
    ds = _run("coulomb", axes, path=path, chunks=(2, 3))
    xr.testing.assert_identical(ds.load(), full)
    lost = sorted(store.done_chunks(path, 2))[::3]
    for i, j in lost:  # as a kill would leave them: labels missing (other files or not)
        (path / "label" / "c" / str(i) / str(j)).unlink()
    ran = []
    original = core.compute_chunk
    monkeypatch.setattr(core, "compute_chunk",
                        lambda task, n=None: ran.append(task.index) or original(task, n))
    xr.testing.assert_identical(_run("coulomb", axes, path=path).load(), full)
    assert sorted(ran) == lost
    ran.clear()
    _run("coulomb", axes, path=path)
    assert ran == []
    xr.testing.assert_identical(fricenv.open_atlas(path).load(), full)


@pytest.mark.parametrize(("change", "match"), [
    ({"settings": SweepSettings(window_min=99.0)}, "setting window_min = 100.0, not 99.0"),
    ({"base": OscillatorParams(lam=0.4)}, "base lam = 0.5, not 0.4"),
    ({"axes": {"u0": U0[:4], "nu": NU[:3]}}, "its u0 grid differs"),
    ({"axes": {"nu": NU[:2], "u0": U0[:3]}}, r"its axes are \['u0', 'nu'\]"),
    ({"chunks": (1, 1)}, r"its chunks are \(2, 2\), not \(1, 1\)"),
    ({"algorithm": 12}, "ALGORITHM"),
])
def test_mismatched_store_refused(tmp_path, change, match):
    path = tmp_path / "a.zarr"
    kw = {"base": OscillatorParams(), "axes": {"u0": U0[:3], "nu": NU[:3]},
          "chunks": (2, 2)}
    _run(kw["base"], kw["axes"], path=path, chunks=kw["chunks"])
    if "algorithm" in change:
        zarr.open_group(path, mode="r+").attrs["algorithm"] = change.pop("algorithm")
    kw.update(change)
    with pytest.raises(ValueError, match=match):
        _run(kw.pop("base"), kw.pop("axes"), path=path, **kw)


def test_foreign_store_refused(tmp_path):
    (tmp_path / "x.zarr").mkdir()
    with pytest.raises(ValueError, match="not a fricenv atlas store"):
        _run("coulomb", {"u0": U0[:2]}, path=tmp_path / "x.zarr")
    (tmp_path / "f").write_text("")
    with pytest.raises(ValueError, match="is a file"):
        _run("coulomb", {"u0": U0[:2]}, path=tmp_path / "f")


@pytest.mark.parametrize(("base", "axes", "error", "match"), [
    ("coulomb", [("u0", [1.0])], TypeError, "axes must be a mapping"),
    ("coulomb", {}, ValueError, "axes is empty"),
    ("coulomb", {"u1": [1.0]}, ValueError, "'u1' is not a parameter an atlas can sweep"),
    ("coulomb", {"u0": []}, ValueError, r"axes\['u0'\] is empty"),
    ("coulomb", {"u0": [[1.0, 2.0]]}, ValueError, "must be 1-d"),
    ("coulomb", {"u0": ["1"]}, TypeError, "real numbers"),
    ("coulomb", {"u0": [1.0, -2.0]}, ValueError, r"u0 must be >= 0.*got -2.0"),
    ("coulomb", {"eta": [0.5, 0.0]}, ValueError, r"eta must be > 0, got 0.0"),
    ("coulomb", {"lam": [np.nan]}, ValueError, "lam must be finite"),
    ("coulomb", {"V": [1e300]}, ValueError, "V must lie within"),
    ("coulomb", {"nu": [0.5, 0.5]}, ValueError, "must not repeat a value, got 0.5"),
    ("coulomb", {"xfs": [2.0, 4.0]}, ValueError, r"xfs = 2.0 < xfk = 2.5"),
    ("coulomb", {"xfk": [2.5, 5.0]}, ValueError, r"xfk = 5.0 gives xfs = 4.0 < xfk = 5.0"),
    (OscillatorParams(u1=1.0), {"u0": [1.0]}, ValueError, "base.u1"),
    ("nonsense", {"u0": [1.0]}, ValueError, "unknown friction law"),
    (3, {"u0": [1.0]}, TypeError, "base must be"),
    ("coulomb", {"eta": [1e-9]}, ValueError, r"scan steps .* \(eta = 1e-09"),
    ("coulomb", {"eta": [0.6, 1e6]}, ValueError, r"stroboscopic samples.*\(at eta = 1000000.0\)"),
])
def test_bad_axes_refused_before_any_cell_runs(monkeypatch, base, axes, error, match):
    monkeypatch.setattr(cells, "run_cells", lambda *a, **k: pytest.fail("a cell ran"))
    with pytest.raises(error, match=match):
        _run(base, axes)


def test_bad_arguments_refused(monkeypatch, tmp_path):
    monkeypatch.setattr(cells, "run_cells", lambda *a, **k: pytest.fail("a cell ran"))
    with pytest.raises(ValueError, match="method 'exact' needs the Coulomb law"):
        _run("coulomb", {"b1": [0.0, 0.2]}, settings=SweepSettings(method="exact"))
    with pytest.raises(TypeError, match="client must be"):
        _run("coulomb", {"u0": [1.0]}, client="tcp://nowhere")
    with pytest.raises(ValueError, match=r"chunks names \['eta'\]"):
        _run("coulomb", {"u0": [1.0]}, chunks={"eta": 1})
    with pytest.raises(ValueError, match=r"chunks\['u0'\] must be an integer >= 1"):
        _run("coulomb", {"u0": [1.0]}, chunks=(0,))
    with pytest.raises(TypeError, match="progress must be a bool"):
        fricenv.atlas("coulomb", {"u0": [1.0]}, progress="no")
    assert not list(tmp_path.iterdir())


KILLED_RUN = """
import sys, numpy as np, fricenv
from fricenv.sweep import SweepSettings
client = None
if len(sys.argv) > 2:
    from distributed import Client
    client = Client(sys.argv[2])
fricenv.atlas("stribeck", {"u0": np.geomspace(0.5, 20, 12), "nu": np.linspace(0.3, 2.3, 12)},
              path=sys.argv[1], chunks=(1, 3), client=client, progress=False,
              settings=SweepSettings(window_min=400.0))
"""


def _kill_mid_run(path: Path, scheduler: str | None = None) -> int:
    """Start a run in a subprocess, SIGKILL it once a few chunks are stored; returns how
    many were."""
    args = [sys.executable, "-c", KILLED_RUN, str(path)] + ([scheduler] if scheduler else [])
    err = path.with_name("stderr.txt")
    with open(err, "w") as fh:
        proc = subprocess.Popen(args, cwd=ROOT, env=_env(), stderr=fh)
    try:
        deadline = time.monotonic() + 120
        while len(store.done_chunks(path, 2)) < 3 and time.monotonic() < deadline:
            assert proc.poll() is None, f"the run ended before it could be killed: " \
                                        f"{err.read_text()[-2000:]}"
            time.sleep(0.02)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    return len(store.done_chunks(path, 2))


@pytest.mark.parametrize("where", ["local", "dask"])
def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path, client, where):
    path = tmp_path / "k.zarr"
    scheduler = client.scheduler.address if where == "dask" else None
    n_done = _kill_mid_run(path, scheduler)
    assert 3 <= n_done < 48, n_done  # killed mid-run (of 48 chunks)
    axes = {"u0": np.geomspace(0.5, 20, 12), "nu": np.linspace(0.3, 2.3, 12)}
    settings = SweepSettings(window_min=400.0)
    resumed = _run("stribeck", axes, path=path, client=client if where == "dask" else None,
                   settings=settings)
    full = _run("stribeck", axes, client=client, chunks=(1, 3), settings=settings)
    xr.testing.assert_identical(resumed.load(), full)


def test_client_memory_bounded_on_a_million_cells(client, tmp_path, monkeypatch):
    held = {}
    monkeypatch.setattr(api, "_distributed",
                        lambda c, tasks: distributed.run_distributed(c, tasks, held))
    axes = {"u0": np.linspace(0.0, 5.0, 100), "nu": np.linspace(0.1, 3.0, 100),
            "eta": np.linspace(0.2, 2.0, 100)}  # 1e6 cells, 62 chunks of 16384
    _run("coulomb", axes, settings=CHEAP, client=client, chunks=(25, 25, 25))
    tracemalloc.start()
    try:
        ds = _run("coulomb", axes, path=tmp_path / "m.zarr", settings=CHEAP, client=client,
                  chunks=(25, 25, 25))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    window = distributed.IN_FLIGHT_PER_THREAD * 2 + 1
    assert held["max_in_flight"] <= window + 1
    # the atlas's variables take 44 MB in memory; the client held a few chunks of 0.7 MB
    assert peak < 16e6, f"client peak {peak / 1e6:.1f} MB"
    assert int((ds.label == -1).sum()) == 0


def test_regime_map_npz_converts(tmp_path):
    m = regime_map("coulomb", U0[:3], NU[:2], progress=False, path=tmp_path / "m.npz")
    ds = fricenv.open_atlas(tmp_path / "m.npz")
    xr.testing.assert_identical(ds, regime_map_dataset(m))
    xr.testing.assert_identical(ds, _run("coulomb", {"u0": U0[:3], "nu": NU[:2]}))

    def stop(rmap, n):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):  # a map cut off after its first chunk
        regime_map("coulomb", U0, NU, progress=False, path=tmp_path / "p.npz",
                   chunk_size=5, callback=stop)
    part = fricenv.open_atlas(tmp_path / "p")
    done = part.label.values != -1
    assert done.sum() == 5
    assert np.all(part.status.values[~done] == -1) and np.all(part.status.values[done] >= 0)
    assert np.isnan(part.v_max.values[~done]).all()


def test_one_axis_store_without_nu_round_trips(tmp_path):
    axes = {"u0": U0[:5]}  # nu fixed by the base: q is a scalar coordinate
    ds = _run("coulomb", axes, path=tmp_path / "one.zarr", chunks=2)
    xr.testing.assert_identical(ds.load(), _run("coulomb", axes))
    assert ds.q.ndim == 0 and int(ds.q) == 1
