"""Atlases as labelled xarray Datasets, and their resumable Zarr stores.

A store is a Zarr (format 3) group on the local file system: one array per variable, all
chunked like the atlas's chunks, with the axes as 1-d coordinate arrays and each array's
``dimension_names`` set, so ``xarray.open_zarr`` reads it as a Dataset. Only the process
that runs the atlas writes to it (workers return their chunks), so a cluster's workers
need no shared file system.

Crash safety: a store is created in a temporary folder and renamed into place, so it
either exists whole or not at all; Zarr writes each chunk file atomically (temporary file,
then rename), and a chunk's ``label`` is written after its other variables, so a stored
label marks a complete chunk. A run killed at any moment (SIGKILL included) thus loses only
the chunks in flight, and the next run with the same arguments computes just the chunks
whose label is missing.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any, Literal

import numpy as np
import xarray as xr
import zarr

from .. import __version__
from ..checks import check_path, got
from ..params import OscillatorParams
from ..regimes import Regime
from ..sweep import ALGORITHM, NOT_COMPUTED, RegimeMap, SweepSettings, plan_cells
from .core import STATUS_NOT_RUN, VARIABLES, AtlasSpec, variables_from_stats

FORMAT = "fricenv.atlas"
FORMAT_VERSION = 1
#: Where the chunk files of an array live in a format-3 store (default chunk key encoding).
_CHUNK_DIR = "c"

_DESCRIPTIONS = {
    "stick_fraction": "share of the measurement window spent stuck",
    "n_stick": "stick phases entered in the window",
    "n_reversal": "direct slip reversals through v = V in the window (no stick)",
    "v_min": "least velocity in the window",
    "v_max": "greatest velocity in the window",
    "period": "response period in common forcing periods (0: none found or not tested)",
    "status": f"kernel status (0: ok; {STATUS_NOT_RUN}: not computed)",
    "label": "regime label, a fricenv.Regime value",
}


def label_attrs() -> dict:
    """The label's flag table (CF ``flag_values`` / ``flag_meanings``), from ``Regime``
    itself so that new members are listed without a change here."""
    return {"long_name": _DESCRIPTIONS["label"],
            "flag_values": [int(r) for r in Regime],
            "flag_meanings": " ".join(r.name for r in Regime),
            "not_computed": NOT_COMPUTED}


def variable_attrs(name: str) -> dict[str, Any]:
    return label_attrs() if name == "label" else {"long_name": _DESCRIPTIONS[name]}


def dataset_attrs(spec: AtlasSpec, algorithm: int = ALGORITHM) -> dict:
    """Dataset attributes: what the cells are (base parameters, settings, the swept axes)
    and which measurement code made them. Nested values are JSON strings, so the Dataset
    also writes to netCDF."""
    return {"format": FORMAT, "format_version": FORMAT_VERSION, "algorithm": int(algorithm),
            "base": json.dumps(spec.base.to_dict(), sort_keys=True),
            "settings": json.dumps(asdict(spec.settings), sort_keys=True),
            "axes": json.dumps(list(spec.axes)), "fricenv_version": __version__}


_Q_ATTRS: dict[str, Any] = {"long_name": "tested denominator of nu (0: not tested)"}


def _q(spec: AtlasSpec) -> tuple[tuple[str, ...], np.ndarray, dict]:
    """The tested denominator of each nu (0: untested), a coordinate along nu."""
    nu = spec.axes.get("nu", np.array([spec.base.nu]))
    # (q depends on nu and the settings alone; a grid point's params were checked to plan)
    first = spec.base.replace(**{k: float(a[0]) for k, a in spec.axes.items()
                                 if k in ("eta", "lam", "b1")})
    q = plan_cells(first, nu, spec.settings).q.astype(np.int16)
    return (("nu",), q, _Q_ATTRS) if "nu" in spec.axes else ((), q[0], _Q_ATTRS)


def to_dataset(spec: AtlasSpec, arrays: dict[str, np.ndarray], algorithm: int = ALGORITHM
               ) -> xr.Dataset:
    """An in-memory atlas: ``arrays`` (shaped like the grid) with the axes as coordinates."""
    dims = spec.names
    coords: dict[str, tuple[Any, ...]] = {k: (k, v) for k, v in spec.axes.items()}
    coords["q"] = _q(spec)
    data = {k: (dims, arrays[k], variable_attrs(k)) for k in VARIABLES}
    return xr.Dataset(data, coords=coords, attrs=dataset_attrs(spec, algorithm))


def regime_map_dataset(rmap: RegimeMap) -> xr.Dataset:
    """A :class:`~fricenv.sweep.RegimeMap` as an atlas over ``(u0, nu)`` (cells not done
    hold the fill values; the map's own algorithm version is kept)."""
    if not isinstance(rmap, RegimeMap):
        raise TypeError(f"rmap must be a fricenv.RegimeMap, {got(rmap)}")
    spec = AtlasSpec(rmap.params, {"u0": np.asarray(rmap.u0, dtype=float),
                                   "nu": np.asarray(rmap.nu, dtype=float)},
                     rmap.settings, tuple(rmap.labels.shape))
    status = np.where(rmap.done, rmap.status, STATUS_NOT_RUN)
    arrays = variables_from_stats(rmap.stats, rmap.period, status, rmap.labels)
    return to_dataset(spec, arrays, int(rmap.meta.get("algorithm", ALGORITHM)))


# -- stores ----------------------------------------------------------------------------
def check_store_path(path: object) -> Path:
    p = check_path("path", path)
    if p.name in ("", ".", ".."):
        raise ValueError(f"path must name a store folder, got {str(path)!r}")
    if p.exists() and not p.is_dir():
        raise ValueError(f"path {str(p)!r} is a file, not a Zarr store (a folder)")
    for q in p.parents:
        if q.exists():
            if not q.is_dir():
                raise ValueError(f"path {str(p)!r}: {str(q)!r} exists and is not a folder")
            break
    return p


def create_store(path: Path, spec: AtlasSpec) -> None:
    """Write an empty store for ``spec`` at ``path`` (built beside it, then renamed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.creating-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        group = zarr.open_group(tmp, mode="w-", zarr_format=3, attributes=dataset_attrs(spec))
        for name, grid in spec.axes.items():
            a = group.create_array(name, shape=grid.shape, dtype="float64", chunks=grid.shape,
                                   dimension_names=[name])
            a[...] = grid
        qdims, q, _ = _q(spec)
        a = group.create_array("q", shape=np.shape(q), dtype="int16", dimension_names=qdims,
                               chunks=np.shape(q), attributes=_Q_ATTRS)
        a[...] = q
        for name, (dtype, fill) in VARIABLES.items():
            group.create_array(name, shape=spec.shape, dtype=dtype, chunks=spec.chunks,
                               fill_value=fill, dimension_names=list(spec.names),
                               attributes={**variable_attrs(name), "coordinates": "q"})
        os.rename(tmp, path)  # fails if a store appeared meanwhile: nothing is overwritten
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _array(group: zarr.Group, name: str) -> zarr.Array:
    """The array ``name`` of an atlas store (a group there means a damaged store)."""
    a = group[name]
    if not isinstance(a, zarr.Array):
        raise ValueError(f"the atlas store's {name!r} is a group, not an array")
    return a


def _open_group(path: Path, mode: Literal["r", "r+"] = "r+") -> zarr.Group:
    """``path``'s store, or ``ValueError`` naming it if it is no fricenv atlas."""
    try:
        group = zarr.open_group(path, mode=mode)
    except Exception as exc:  # (zarr raises several kinds for a folder it cannot read)
        raise ValueError(f"{path} is not a fricenv atlas store ({exc})") from None
    attrs = dict(group.attrs)
    if attrs.get("format") != FORMAT or attrs.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{path} is not a fricenv atlas store (format "
                         f"{attrs.get('format')!r} version {attrs.get('format_version')!r})")
    return group


def _stored_spec_mismatch(group: zarr.Group, spec: AtlasSpec, chunks_given: bool
                          ) -> str | None:
    """What differs between the stored atlas and ``spec`` (None: nothing)."""
    attrs = dict(group.attrs)
    if attrs.get("algorithm") != ALGORITHM:
        return (f"it was made by measurement code version (ALGORITHM) "
                f"{attrs.get('algorithm')!r}, this fricenv measures with {ALGORITHM}")
    try:
        axes = json.loads(str(attrs["axes"]))
        base = OscillatorParams(**json.loads(str(attrs["base"])))
        settings = SweepSettings(**json.loads(str(attrs["settings"])))
    except (KeyError, TypeError, ValueError) as exc:
        return f"its attributes are damaged ({exc!r})"
    if axes != list(spec.axes):
        return f"its axes are {axes}, not {list(spec.axes)}"
    stored = AtlasSpec(base, spec.axes, settings, spec.chunks)
    if stored.base_key() != spec.base_key():
        diff = [k for k, v in spec.base_key().items() if stored.base_key()[k] != v]
        return ", ".join(f"base {k} = {stored.base_key()[k]!r}, not {spec.base_key()[k]!r}"
                         for k in diff)
    if settings != spec.settings:
        a, b = asdict(settings), asdict(spec.settings)
        return ", ".join(f"setting {f.name} = {a[f.name]!r}, not {b[f.name]!r}"
                         for f in fields(SweepSettings) if a[f.name] != b[f.name])
    for name, grid in spec.axes.items():
        old = np.asarray(_array(group, name)[...])
        if old.shape != grid.shape or not np.array_equal(old, grid):
            return (f"its {name} grid differs ({old.size} values from {float(old.min())!r} "
                    f"to {float(old.max())!r}; given {grid.size} from "
                    f"{float(grid.min())!r} to {float(grid.max())!r})")
    stored_chunks = tuple(_array(group, "label").chunks)
    if chunks_given and stored_chunks != spec.chunks:
        return f"its chunks are {stored_chunks}, not {spec.chunks}"
    return None


def open_for_resume(path: Path, spec: AtlasSpec, chunks_given: bool
                    ) -> tuple[zarr.Group, tuple[int, ...]]:
    """The store at ``path`` and its chunk shape, if it holds this atlas; else
    ``ValueError`` naming what differs."""
    group = _open_group(path)
    why = _stored_spec_mismatch(group, spec, chunks_given)
    if why:
        raise ValueError(f"{path} holds another atlas: {why}; remove it or choose "
                         "another path")
    for k in VARIABLES:
        if k not in group or tuple(_array(group, k).shape) != spec.shape:
            raise ValueError(f"{path} is a damaged atlas store: no {k} of shape {spec.shape}")
    return group, tuple(_array(group, "label").chunks)


def done_chunks(path: Path, ndim: int) -> set[tuple[int, ...]]:
    """Indices of the chunks whose label is stored (complete chunks), from the file names
    (no chunk is read; safe while a run writes)."""
    root = path / "label" / _CHUNK_DIR
    done: set[tuple[int, ...]] = set()
    if not root.is_dir():
        return done
    for dirpath, _, files in os.walk(root):
        rel = Path(dirpath).relative_to(root).parts
        for f in files:
            if re.fullmatch(r"\d+", f) and len(rel) + 1 == ndim:
                done.add(tuple(int(p) for p in rel) + (int(f),))
    return done


def remove_partial_writes(path: Path) -> None:
    """Delete the temporary files of chunk writes that a kill cut off. Only for the run
    that resumes the store: a running writer's own temporary files would go too."""
    for f in path.rglob("*.partial"):
        f.unlink(missing_ok=True)


class ZarrSink:
    """Writes chunks into an open store: the label last, as the chunk's completion mark."""

    def __init__(self, group: zarr.Group) -> None:
        self.arrays = {k: _array(group, k) for k in VARIABLES}  # (VARIABLES ends with label)

    def __call__(self, slices: tuple[slice, ...], values: dict[str, np.ndarray]) -> None:
        for k, arr in self.arrays.items():
            arr[slices] = values[k]


def open_atlas(path: str | os.PathLike, chunks: Any = None) -> xr.Dataset:
    """Open an atlas: a Zarr store written by :func:`fricenv.atlas` (lazily: cells are
    read when used; ``chunks`` as in ``xarray.open_zarr`` gives Dask arrays instead), or a
    regime map's ``.npz`` file (converted in memory)."""
    p = check_path("path", path)
    if p.suffix == ".npz" or (not p.exists() and p.with_name(p.name + ".npz").exists()):
        return RegimeMap.load(p).to_xarray()
    if not p.exists():
        raise FileNotFoundError(f"no atlas at {str(p)!r}")
    _open_group(p, mode="r")
    ds = xr.open_zarr(p, consolidated=False, chunks=chunks, mask_and_scale=False,
                      decode_times=False)
    return ds
