"""Atlases as labelled xarray Datasets, and their resumable Zarr stores.

A store is a Zarr (format 3) group on the local file system: one array per variable, all
chunked like the atlas's chunks, with the axes as 1-d coordinate arrays and each array's
``dimension_names`` set, so ``xarray.open_zarr`` reads it as a Dataset. The group's
metadata document holds the consolidated metadata of its arrays (Zarr-Python's
``consolidated_metadata`` field), listed in the atlas's order (the axes, ``q``, then
:data:`~fricenv.atlas.core.VARIABLES`): plain ``xarray.open_zarr(path)`` opens it without a
warning and with the data variables in that order. Only the process that runs the atlas
writes to it (workers return their chunks), so a cluster's workers need no shared file
system.

Crash safety: a store is created in a temporary folder and renamed into place, so it
either exists whole or not at all; Zarr writes each chunk file atomically (temporary file,
then rename), every chunk file is written (fill values included), and a chunk's ``label``
is written after its other variables. A chunk is complete when every variable's file is
there and matches its checksum. A run killed at any moment (SIGKILL included) thus loses
only the chunks in flight, and the next run with the same arguments computes just the
chunks not complete.

Integrity: each chunk file ends in a CRC-32C of its compressed bytes (Zarr's ``crc32c``
codec), and the group's attributes hold a CRC-32C of every metadata document (the group's
own covers its consolidated copies of the others). Those checksums bind a file to its
bytes, not to its place: a chunk file moved to another index or variable, or copied from
another atlas of the same shape, still matches its own. So each chunk also has a record,
``label/records/<i>.<j>...json`` (inside the label array's folder, where Zarr never
looks), holding for every variable a digest of the file's bytes keyed by the store's
random id, the variable's name and the chunk's index, written after the chunk's files. Opening or
resuming a store checks all of them first (reading each file once, without decompressing
it), so that damage or a misplaced file is a ``ValueError`` naming the store and the array
or chunk, or, when resuming, a chunk computed again: a flipped bit never reads as a
changed value, a chunk file never as another cell's. One run writes a store at a time: it
holds the OS lock of ``<store>.lock``, beside the store, on the store's resolved path
(:func:`fricenv.mapfile.writer_lock`).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import uuid
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any, Literal

import google_crc32c
import numpy as np
import xarray as xr
import zarr
from zarr.codecs import Crc32cCodec, ZstdCodec
from zarr.core.array_spec import ArrayConfig

from .._version import __version__
from ..cells import NOT_COMPUTED, SweepSettings, plan_cells
from ..checks import check_path, got
from ..maps import ALGORITHM, RegimeMap
from ..params import OscillatorParams
from ..regimes import Regime
from .core import STATUS_NOT_RUN, VARIABLES, AtlasSpec, chunk_slices, variables_from_stats

FORMAT = "fricenv.atlas"
#: Version 2: chunks carry checksums, metadata documents have theirs in the group's
#: attributes, and every chunk file is written (fill values included).
FORMAT_VERSION = 4
#: Version 3: each chunk has a record binding its files to the store, variable and index.
#: Version 4: the ``lyapunov`` variable.
#: Group attribute holding the store's random id, which the records' checksums cover.
_STORE_ID = "store_id"
#: Folder of the chunk records, inside the label array's folder (Zarr lists no such
#: folder as a node of the hierarchy, so plain xarray and Zarr read the store as before).
_RECORDS = "records"
#: Where the chunk files of an array live in a format-3 store (default chunk key encoding).
_CHUNK_DIR = "c"
#: A Zarr node's metadata document.
_META = "zarr.json"
#: Group attribute holding the CRC-32C of each metadata document (a JSON object by array
#: name; "" is the group's own, without this attribute).
_CHECKSUMS = "metadata_checksums"
#: Zarr's default compressor, then a CRC-32C of the compressed bytes: any damage to a
#: chunk file fails the checksum before anything is decompressed.
_COMPRESSORS = (ZstdCodec(level=0, checksum=False), Crc32cCodec())
#: Write chunks holding only fill values too: a chunk file missing is a chunk not written.
_WRITE_EMPTY = ArrayConfig(order="C", write_empty_chunks=True)
#: States of a chunk file (see _chunk_state).
_MISSING = "is missing"
_BAD_SUM = "does not match its checksum"
_MISPLACED = ("is not the file written there (moved from another chunk or variable, copied "
              "from another store, or its write was cut off)")

_DESCRIPTIONS = {
    "stick_fraction": "share of the measurement window spent stuck",
    "n_stick": "stick phases entered in the window",
    "n_reversal": "direct slip reversals through v = V in the window (no stick)",
    "v_min": "least velocity in the window",
    "v_max": "greatest velocity in the window",
    "period": "response period in common forcing periods (0: none found or not tested)",
    "status": f"kernel status (0: ok; {STATUS_NOT_RUN}: not computed)",
    "lyapunov": "largest Lyapunov exponent over the window (NaN: not measured)",
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
    """A :class:`~fricenv.RegimeMap` as an atlas over ``(u0, nu)`` (cells not done
    hold the fill values; the map's own algorithm version is kept)."""
    if not isinstance(rmap, RegimeMap):
        raise TypeError(f"rmap must be a fricenv.RegimeMap, {got(rmap)}")
    spec = AtlasSpec(rmap.params, {"u0": np.asarray(rmap.u0, dtype=float),
                                   "nu": np.asarray(rmap.nu, dtype=float)},
                     rmap.settings, tuple(rmap.labels.shape))
    status = np.where(rmap.done, rmap.status, STATUS_NOT_RUN)
    arrays = variables_from_stats(rmap.stats, rmap.period, status, rmap.labels,
                                  rmap.lyapunov)
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


def _digest(meta: Any) -> str:
    """CRC-32C of a metadata document in canonical form (sorted keys, no spaces), so that
    only a change of content, never of layout, changes it."""
    text = json.dumps(meta, sort_keys=True, separators=(",", ":"))
    return f"{google_crc32c.value(text.encode()):08x}"


def _group_meta(meta: dict) -> dict:
    """The group's metadata as its checksum covers it: without the checksums themselves."""
    attrs = {k: v for k, v in meta.get("attributes", {}).items() if k != _CHECKSUMS}
    return {**meta, "attributes": attrs}


def _array_names(axes: Sequence[str]) -> list[str]:
    return [*axes, "q", *VARIABLES]


def create_store(path: Path, spec: AtlasSpec) -> None:
    """Write an empty store for ``spec`` at ``path`` (built beside it, then renamed).

    Every array's chunks end in a CRC-32C (codec ``crc32c`` after ``zstd``), every chunk
    file is written even when it holds only fill values (so a missing file is a chunk not
    written), and the group records a checksum of each array's metadata and of its own.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.creating-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    kw: dict[str, Any] = {"compressors": _COMPRESSORS, "config": _WRITE_EMPTY}
    try:
        group = zarr.open_group(tmp, mode="w-", zarr_format=3,
                                attributes={**dataset_attrs(spec), _STORE_ID: uuid.uuid4().hex})
        for name, grid in spec.axes.items():
            a = group.create_array(name, shape=grid.shape, dtype="float64", chunks=grid.shape,
                                   dimension_names=[name], **kw)
            a[...] = grid
        qdims, q, _ = _q(spec)
        a = group.create_array("q", shape=np.shape(q), dtype="int16", dimension_names=qdims,
                               chunks=np.shape(q), attributes=_Q_ATTRS, **kw)
        a[...] = q
        for name, (dtype, fill) in VARIABLES.items():
            group.create_array(name, shape=spec.shape, dtype=dtype, chunks=spec.chunks,
                               fill_value=fill, dimension_names=list(spec.names),
                               attributes={**variable_attrs(name), "coordinates": "q"}, **kw)
        _write_group_meta(tmp, _array_names(spec.names))
        os.rename(tmp, path)  # fails if a store appeared meanwhile: nothing is overwritten
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _write_group_meta(tmp: Path, names: Sequence[str]) -> None:
    """Finish the group's metadata document of a store being created: the consolidated
    metadata of the arrays ``names``, in that order (xarray lists the variables in it;
    Zarr's own ``consolidate_metadata`` sorts them by name), then the checksums of every
    metadata document, the group's own over the consolidated copies too."""
    docs = {name: json.loads((tmp / name / _META).read_bytes()) for name in names}
    meta = json.loads((tmp / _META).read_bytes())
    meta["consolidated_metadata"] = {"kind": "inline", "must_understand": False,
                                     "metadata": docs}
    sums = {name: _digest(doc) for name, doc in docs.items()}
    sums[""] = _digest(_group_meta(meta))
    meta.setdefault("attributes", {})[_CHECKSUMS] = json.dumps(sums, sort_keys=True)
    (tmp / _META).write_text(json.dumps(meta, indent=2))


def _damaged(path: Path, what: str) -> ValueError:
    """The error for a store whose contents fail a check (raise it ``from`` the cause)."""
    return ValueError(f"{path} is a damaged atlas store: {what}; remove it and run the "
                      "atlas again, or restore it from a copy")


def _read_meta(path: Path, name: str) -> dict:
    """The metadata document (``zarr.json``) of the array ``name`` ('': the group)."""
    rel = f"{name}/{_META}" if name else _META
    what = f"the metadata of array {name!r}" if name else "the group's metadata"
    try:
        meta = json.loads((path / rel).read_bytes())
    except FileNotFoundError as exc:
        if not name:
            raise ValueError(f"{path} is not a fricenv atlas store (no {_META})") from exc
        raise _damaged(path, f"{what} ({rel}) is missing") from exc
    except (OSError, ValueError) as exc:  # (JSONDecodeError, UnicodeDecodeError)
        raise _damaged(path, f"{what} ({rel}) cannot be read: {type(exc).__name__}: "
                             f"{exc}") from exc
    if not isinstance(meta, dict) or not isinstance(meta.get("attributes", {}), dict):
        raise _damaged(path, f"{what} ({rel}) is not a metadata document")
    return meta


def _check_format(path: Path, attrs: dict) -> None:
    if attrs.get("format") != FORMAT:
        raise ValueError(f"{path} is not a fricenv atlas store (format "
                         f"{attrs.get('format')!r} version {attrs.get('format_version')!r})")
    version = attrs.get("format_version")
    if version == 1:
        raise ValueError(f"{path} is a fricenv atlas store of format version 1, whose chunks "
                         f"carry no checksums; this fricenv reads version {FORMAT_VERSION} "
                         "only: remove it and run the atlas again (xarray.open_zarr still "
                         "reads it, unchecked)")
    if version == 2:
        raise ValueError(f"{path} is a fricenv atlas store of format version 2, whose chunks "
                         "are not bound to their place (a chunk moved or copied from another "
                         f"atlas read as this one's); this fricenv reads version "
                         f"{FORMAT_VERSION} only: remove it and run the atlas again "
                         "(xarray.open_zarr still reads it)")
    if version == 3:
        raise ValueError(f"{path} is a fricenv atlas store of format version 3, without the "
                         f"lyapunov variable; this fricenv reads version {FORMAT_VERSION} "
                         "only: remove it and run the atlas again (xarray.open_zarr still "
                         "reads it)")
    if version != FORMAT_VERSION:
        raise ValueError(f"{path} is a fricenv atlas store of format version {version!r}; "
                         f"this fricenv reads version {FORMAT_VERSION}")


def _check_algorithm(path: Path, attrs: dict) -> None:
    if attrs.get("algorithm") != ALGORITHM:
        raise ValueError(f"{path} holds another atlas: it was made by measurement code "
                         f"version (ALGORITHM) {attrs.get('algorithm')!r}, this fricenv "
                         f"measures with {ALGORITHM}; remove it or choose another path")


def _check_metadata(path: Path, resuming: bool) -> dict:
    """The group's attributes, once every metadata document of the store has been read and
    matched against the checksum recorded for it (``ValueError`` naming the document)."""
    meta = _read_meta(path, "")
    attrs = meta.get("attributes", {})
    _check_format(path, attrs)
    if resuming:  # (named before the checksums: the algorithm is the likelier reason)
        _check_algorithm(path, attrs)
    try:
        sums = json.loads(str(attrs[_CHECKSUMS]))
        axes = json.loads(str(attrs["axes"]))
        if not (isinstance(sums, dict) and isinstance(axes, list)
                and all(isinstance(a, str) for a in axes)):
            raise TypeError("not a mapping and a list of names")
    except (KeyError, TypeError, ValueError) as exc:
        raise _damaged(path, f"its attributes {_CHECKSUMS!r} and 'axes' cannot be read "
                             f"({type(exc).__name__}: {exc})") from exc
    if sums.get("") != _digest(_group_meta(meta)):
        raise _damaged(path, f"the group's metadata ({_META}) does not match its checksum")
    for name in _array_names(axes):
        if sums.get(name) != _digest(_read_meta(path, name)):
            raise _damaged(path, f"the metadata of array {name!r} ({name}/{_META}) does not "
                                 "match its checksum")
    return attrs


def _chunk_file(path: Path, name: str, index: tuple[int, ...]) -> Path:
    """Where chunk ``index`` of array ``name`` lives (default chunk key encoding)."""
    return path.joinpath(name, _CHUNK_DIR, *(str(i) for i in index))


def _chunk_state(path: Path, name: str, index: tuple[int, ...]) -> str:
    """'' if the chunk file is there and matches its checksum, else what is wrong. The
    checksum is read from the file's last 4 bytes, as the ``crc32c`` codec writes it, so
    no chunk is decompressed."""
    try:
        data = _chunk_file(path, name, index).read_bytes()
    except FileNotFoundError:
        return _MISSING
    except OSError as exc:
        return f"cannot be read ({exc})"
    if len(data) < 4 or google_crc32c.value(data[:-4]) != int.from_bytes(data[-4:], "little"):
        return _BAD_SUM
    return ""


def _record_file(path: Path, index: tuple[int, ...]) -> Path:
    """Where chunk ``index``'s record lives (see the module's docstring)."""
    return path / "label" / _RECORDS / (".".join(str(i) for i in index) + ".json")


def _bound_sum(store_id: str, name: str, index: tuple[int, ...], data: bytes) -> str:
    """A BLAKE2b digest (64 bits) of a chunk file's place (its store, variable and index)
    and bytes: the same bytes at another place give another sum. Not a CRC: a chunk file
    ends in the CRC-32C of its other bytes, and the CRC-32C of any such file after a fixed
    prefix is one and the same constant, whatever the file holds."""
    h = hashlib.blake2b(digest_size=8, person=b"fricenv-chunk")
    h.update(f"{store_id}/{name}/{'.'.join(str(i) for i in index)}\n".encode())
    h.update(data)
    return h.hexdigest()


def _read_record(path: Path, index: tuple[int, ...]) -> dict:
    """Chunk ``index``'s record (empty when missing or unreadable: then no file of the
    chunk is bound, and the chunk counts as damaged, or in flight without its label)."""
    try:
        record = json.loads(_record_file(path, index).read_bytes())
    except (OSError, ValueError):
        return {}
    return record if isinstance(record, dict) else {}


def write_record(path: Path, store_id: str, index: tuple[int, ...]) -> None:
    """Bind chunk ``index``'s files, as they are now, to their place: the record is
    written to a temporary file and renamed, so it is whole or absent."""
    sums = {k: _bound_sum(store_id, k, index, _chunk_file(path, k, index).read_bytes())
            for k in VARIABLES}
    file = _record_file(path, index)
    file.parent.mkdir(exist_ok=True)
    tmp = file.with_name(file.name + ".partial")
    tmp.write_text(json.dumps(sums, sort_keys=True))
    os.replace(tmp, file)


def _variable_state(path: Path, store_id: str, name: str, index: tuple[int, ...],
                    record: dict) -> str:
    """As :func:`_chunk_state`, and for an intact file whether it is the one its chunk's
    record binds to this store, variable and index (``_MISPLACED`` otherwise)."""
    try:
        data = _chunk_file(path, name, index).read_bytes()
    except FileNotFoundError:
        return _MISSING
    except OSError as exc:
        return f"cannot be read ({exc})"
    if len(data) < 4 or google_crc32c.value(data[:-4]) != int.from_bytes(data[-4:], "little"):
        return _BAD_SUM
    if record.get(name) != _bound_sum(store_id, name, index, data):
        return _MISPLACED
    return ""


@dataclass
class StoreCheck:
    """What a store holds, all of it checked: its atlas, and the state of its chunks."""

    path: Path
    group: zarr.Group
    spec: AtlasSpec  # as stored
    complete: set[tuple[int, ...]]  # every variable's chunk there and intact
    damaged: list[tuple[tuple[int, ...], str, str]]  # (chunk, variable, what is wrong)

    def raise_damage(self) -> None:
        """``ValueError`` naming the first damaged chunk (and counting the others)."""
        if self.damaged:
            index, name, why = self.damaged[0]
            more = len(self.damaged) - 1
            raise ValueError(
                f"{self.path} is a damaged atlas store: chunk {index} of variable {name!r} "
                f"({_chunk_file(Path(''), name, index)}) {why}"
                + (f" ({more} more damaged chunk files)" if more else "")
                + "; run the atlas again with the same arguments to recompute it")


def _read_coordinate(path: Path, group: zarr.Group, name: str) -> np.ndarray:
    """A coordinate array's values, its one chunk checked first."""
    a = _array(path, group, name)
    why = _chunk_state(path, name, (0,) * a.ndim)
    if why:
        raise _damaged(path, f"the chunk of coordinate {name!r} {why}")
    try:
        return np.asarray(a[...])
    except Exception as exc:  # (a decoding error: codecs raise several kinds)
        raise _damaged(path, f"coordinate {name!r} cannot be decoded "
                             f"({type(exc).__name__}: {exc})") from exc


def check_store(path: Path, mode: Literal["r", "r+"] = "r") -> StoreCheck:
    """Open the store at ``path`` and check everything in it: each metadata document
    against its checksum, each coordinate, and each chunk file of each variable against
    the checksum at its end. ``ValueError`` naming the store and what is wrong for
    anything but chunks; the state of the chunks is returned (``mode="r+"``: for a run
    that resumes, which recomputes damaged chunks instead)."""
    attrs = _check_metadata(path, resuming=mode == "r+")
    try:
        group = zarr.open_group(path, mode=mode)
    except Exception as exc:  # (zarr raises several kinds for a store it cannot read)
        raise _damaged(path, f"Zarr cannot open it ({type(exc).__name__}: {exc})") from exc
    names = json.loads(str(attrs["axes"]))
    axes = {k: _read_coordinate(path, group, k) for k in names}
    _read_coordinate(path, group, "q")
    try:
        base = OscillatorParams(**json.loads(str(attrs["base"])))
        settings = SweepSettings(**json.loads(str(attrs["settings"])))
    except (KeyError, TypeError, ValueError) as exc:
        raise _damaged(path, f"its attributes 'base' and 'settings' cannot be read "
                             f"({type(exc).__name__}: {exc})") from exc
    arrays = {k: _array(path, group, k) for k in VARIABLES}
    shape = tuple(a.size for a in axes.values())
    for k, a in arrays.items():
        if tuple(a.shape) != shape:
            raise _damaged(path, f"variable {k!r} has shape {tuple(a.shape)}, its axes "
                                 f"{shape}")
    spec = AtlasSpec(base, axes, settings, tuple(arrays["label"].chunks))
    store_id = attrs.get(_STORE_ID)
    if not isinstance(store_id, str) or not store_id:
        raise _damaged(path, f"its attribute {_STORE_ID!r} is missing")
    complete, damaged = _check_chunks(path, store_id, spec)
    return StoreCheck(path, group, spec, complete, damaged)


def _check_chunks(path: Path, store_id: str, spec: AtlasSpec
                  ) -> tuple[set[tuple[int, ...]], list[tuple[tuple[int, ...], str, str]]]:
    """The complete chunks (each variable's file there, intact and bound to its place by
    the chunk's record), and the damaged chunk files: those failing their checksum or
    their record, and the files missing from a chunk whose label, written last, is
    there."""
    complete: set[tuple[int, ...]] = set()
    damaged = []
    for index in np.ndindex(*spec.chunk_grid):
        record = _read_record(path, index)
        states = {k: _variable_state(path, store_id, k, index, record) for k in VARIABLES}
        if not any(states.values()):
            complete.add(index)
            continue
        label_written = states["label"] != _MISSING
        for k, why in states.items():
            # (without its label a chunk was in flight: files written before the label
            # are not bound yet, and its cells read as not computed)
            if why and (why not in (_MISSING, _MISPLACED) or label_written):
                damaged.append((index, k, why))
    return complete, damaged


def _array(path: Path, group: zarr.Group, name: str) -> zarr.Array:
    """The array ``name`` of an atlas store (``ValueError`` naming it if unreadable)."""
    try:
        a = group[name]
    except Exception as exc:  # (KeyError, or whatever zarr's parsers raise)
        raise _damaged(path, f"array {name!r} cannot be opened "
                             f"({type(exc).__name__}: {exc})") from exc
    if not isinstance(a, zarr.Array):
        raise _damaged(path, f"{name!r} is a group, not an array")
    return a


def _stored_spec_mismatch(stored: StoreCheck, spec: AtlasSpec, chunks_given: bool
                          ) -> str | None:
    """What differs between the stored atlas and ``spec`` (None: nothing)."""
    old = stored.spec
    if list(old.axes) != list(spec.axes):
        return f"its axes are {list(old.axes)}, not {list(spec.axes)}"
    on_grid = replace(old, axes=spec.axes)
    if on_grid.base_key() != spec.base_key():
        a, b = on_grid.base_key(), spec.base_key()
        return ", ".join(f"base {k} = {a[k]!r}, not {v!r}" for k, v in b.items() if a[k] != v)
    if old.settings != spec.settings:
        a, b = asdict(old.settings), asdict(spec.settings)
        return ", ".join(f"setting {f.name} = {a[f.name]!r}, not {b[f.name]!r}"
                         for f in fields(SweepSettings) if a[f.name] != b[f.name])
    for name, grid in spec.axes.items():
        was = old.axes[name]
        if was.shape != grid.shape:
            return f"its {name} grid differs: it has {was.size} values, not {grid.size}"
        differ = np.flatnonzero(was != grid)
        if differ.size:
            k = int(differ[0])
            return (f"its {name} grid differs: first at index {k}, stored "
                    f"{float(was[k])!r}, given {float(grid[k])!r} ({differ.size} of "
                    f"{grid.size} values differ)")
    if chunks_given and old.chunks != spec.chunks:
        return f"its chunks are {old.chunks}, not {spec.chunks}"
    return None


def open_for_resume(path: Path, spec: AtlasSpec, chunks_given: bool
                    ) -> tuple[zarr.Group, tuple[int, ...], list[tuple[int, ...]],
                               dict[tuple[int, ...], dict[str, np.ndarray]]]:
    """The store at ``path``, its chunk shape, the chunks still to compute (missing or
    damaged ones, with a warning naming the damage, and those a stopped run left part
    done) and the stored variables of the part-done ones, if it holds this atlas; else
    ``ValueError`` naming what differs. The caller holds the store's writer lock."""
    stored = check_store(path, mode="r+")
    why = _stored_spec_mismatch(stored, spec, chunks_given)
    if why:
        raise ValueError(f"{path} holds another atlas: {why}; remove it or choose "
                         "another path")
    if stored.damaged:
        index, name, what = stored.damaged[0]
        warnings.warn(f"{path}: {len({d[0] for d in stored.damaged})} damaged chunks are "
                      f"computed again (first: chunk {index} of {name!r} {what})",
                      stacklevel=3)
    remove_partial_writes(path)
    part_done = _part_done_chunks(path, stored)
    todo = [i for i in np.ndindex(*stored.spec.chunk_grid)
            if i not in stored.complete or i in part_done]
    return stored.group, stored.spec.chunks, todo, part_done


def _part_done_chunks(path: Path, stored: StoreCheck
                      ) -> dict[tuple[int, ...], dict[str, np.ndarray]]:
    """The variables of each intact chunk that holds cells not computed: a run stopped by
    Ctrl-C or SIGTERM stores the cells it finished in a chunk, the others at their fill
    values. A cell is done when its label is stored (the label is written last)."""
    arrays = {k: _array(path, stored.group, k) for k in VARIABLES}
    out = {}
    for index in sorted(stored.complete):
        sl = chunk_slices(stored.spec, index)
        if np.any(arrays["label"][sl] == NOT_COMPUTED):
            out[index] = {k: np.asarray(a[sl]) for k, a in arrays.items()}
    return out


def done_chunks(path: Path, ndim: int) -> set[tuple[int, ...]]:
    """Indices of the chunks whose label is stored, from the file names: a count of the
    progress (no chunk is read; safe while a run writes). A run that resumes checks every
    chunk file instead (:func:`check_store`)."""
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
    """Writes chunks into an open store: the label last, so that a label file whose chunk
    lacks another variable's file is known to be damage, not a write cut off; then the
    chunk's record, which binds its files to their place."""

    def __init__(self, path: Path, group: zarr.Group) -> None:
        self.path = path
        self.store_id = str(group.attrs[_STORE_ID])
        self.arrays = {k: _array(path, group, k).with_config(_WRITE_EMPTY)
                       for k in VARIABLES}  # (VARIABLES ends with label)
        self.chunks = tuple(self.arrays["label"].chunks)

    def __call__(self, slices: tuple[slice, ...], values: dict[str, np.ndarray]) -> None:
        for k, arr in self.arrays.items():
            arr[slices] = values[k]
        index = tuple(s.start // c for s, c in zip(slices, self.chunks, strict=True))
        write_record(self.path, self.store_id, index)


def open_atlas(path: str | os.PathLike, chunks: Any = None) -> xr.Dataset:
    """Open an atlas: a Zarr store written by :func:`fricenv.atlas` (lazily: cells are
    read when used; ``chunks`` as in ``xarray.open_zarr`` gives Dask arrays instead), or a
    regime map's ``.npz`` file (converted in memory).

    A store is checked first, whole (metadata, coordinates and every chunk file against
    its checksum; a few milliseconds per megabyte): ``ValueError`` naming the store and
    the damaged array or chunk. Chunks of an interrupted run that were never finished
    read as not computed."""
    p = check_path("path", path)
    if p.suffix == ".npz" or (not p.exists() and p.with_name(p.name + ".npz").exists()):
        return regime_map_dataset(RegimeMap.load(p))
    if not p.exists():
        raise FileNotFoundError(f"no atlas at {str(p)!r}")
    if not p.is_dir():
        raise ValueError(f"{p} is not a fricenv atlas store (not a folder)")
    check_store(p).raise_damage()
    ds = xr.open_zarr(p, consolidated=False, chunks=chunks, mask_and_scale=False,
                      decode_times=False)
    ds = ds[list(VARIABLES)]  # (the documented order, also for a store not consolidated)
    ds.attrs.pop(_CHECKSUMS, None)
    ds.attrs.pop(_STORE_ID, None)
    return ds
