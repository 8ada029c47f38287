"""Atlas stores open warning-free in plain xarray, with the variables in the documented
order (the axes, q, then fricenv.atlas.core.VARIABLES), and the metadata checksums cover
the consolidated copy."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import xarray as xr

import fricenv
from fricenv.atlas.core import VARIABLES

ORDER = ["stick_fraction", "n_stick", "n_reversal", "v_min", "v_max", "period", "status",
         "lyapunov", "label"]


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("open") / "a.zarr"
    fricenv.atlas("coulomb", {"u0": np.array([0.5, 2.0, 8.0]), "nu": np.array([0.5, 1.5])},
                  path=path, chunks=2, progress=False)
    return path


def test_plain_open_zarr_is_warning_free_and_ordered(store):
    assert list(VARIABLES) == ORDER  # (the order the atlas module docstring states)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = xr.open_zarr(store)
        labels = ds["label"].values
    assert list(ds.data_vars) == ORDER
    assert list(ds.dims) == ["u0", "nu"] and "q" in ds.coords
    checked = fricenv.open_atlas(store)
    assert list(checked.data_vars) == ORDER
    assert np.array_equal(checked["label"].values, labels)
    fresh = fricenv.atlas("coulomb", {"u0": np.array([0.5, 2.0, 8.0]),
                                      "nu": np.array([0.5, 1.5])}, progress=False)
    assert list(fresh.data_vars) == ORDER  # (in memory, no store)
    assert np.array_equal(fresh["label"].values, labels)


def test_damaged_consolidated_copy_is_named(store, tmp_path):
    """The group's checksum covers the consolidated copies: a changed copy is damage,
    even though each array's own metadata document is intact."""
    import shutil

    copy = tmp_path / "b.zarr"
    shutil.copytree(store, copy)
    meta = json.loads((copy / "zarr.json").read_text())
    meta["consolidated_metadata"]["metadata"]["label"]["fill_value"] = 7
    (copy / "zarr.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=r"the group's metadata \(zarr.json\) does not "
                                         "match its checksum"):
        fricenv.open_atlas(copy)
