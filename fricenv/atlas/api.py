"""``fricenv.atlas``: validate, allocate or open the store, run the chunks, store them."""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from dataclasses import replace
from typing import Any

import numba
import numpy as np
import xarray as xr

from ..checks import check_bool, got
from ..mapfile import writer_lock
from ..params import OscillatorParams
from ..sweep import SweepSettings
from .core import AtlasSpec, chunk_slices, chunk_tasks, empty_variables, make_spec, run_local
from .store import (
    ZarrSink,
    check_store_path,
    create_store,
    open_atlas,
    open_for_resume,
    to_dataset,
)


def _executor_threads(client: Any) -> int:
    """Threads that will run chunks at once (sets the default chunk size)."""
    if client is None:
        return numba.get_num_threads()
    from .distributed import total_threads

    return total_threads(client)


def _check_client(client: object) -> None:
    if client is None:
        return
    from distributed import Client

    if not isinstance(client, Client):
        raise TypeError(f"client must be a dask.distributed.Client or None, {got(client)}")


def atlas(base: OscillatorParams | str, axes: Mapping[str, object],
          path: str | os.PathLike | None = None, client: object = None,
          chunks: int | Mapping[str, int] | tuple[int, ...] | None = None,
          settings: SweepSettings | None = None, progress: bool = True) -> xr.Dataset:
    """Regime labels and window statistics over any volume of parameters.

    ``base`` (an :class:`~fricenv.OscillatorParams` or a friction-law name for the paper's
    defaults) fixes every parameter that ``axes`` does not sweep; ``axes`` maps parameter
    names (``u0, nu, eta, lam, V, xfk, xfs, b1, b3``) to 1-d grids, in the order of the
    result's dimensions. Each cell is measured exactly as :func:`fricenv.regime_map`
    measures it (same transient, window, periodicity test and label), bit for bit.

    ``path``: a Zarr store (a folder) that chunks stream into as they finish; run again
    with the same arguments, only the missing or damaged chunks are computed (every chunk
    carries a checksum); a store of another atlas, or with damaged metadata, raises
    ``ValueError``, and a store that another run is writing raises
    :class:`~fricenv.MapInUseError`. ``client``: a ``dask.distributed.Client`` whose workers
    run the chunks (None: this machine's numba threads). ``chunks``: cells per chunk (an
    int), or chunk lengths per axis (a mapping or a tuple); default about 32 chunks per
    thread, 256 to 16384 cells each, or the store's when resuming. ``settings``: as for
    regime maps. ``progress``: a tqdm bar over the cells.

    Returns an ``xarray.Dataset`` with one dimension per axis and the variables
    ``label, stick_fraction, n_stick, n_reversal, v_min, v_max, period, status`` (and
    ``q``, the tested denominator of nu, as a coordinate); read lazily from the store when
    ``path`` is given. Everything is checked before any cell runs (``TypeError`` /
    ``ValueError`` naming the field and the value).
    """
    progress = check_bool("progress", progress)
    _check_client(client)
    store = None if path is None else check_store_path(path)
    spec = make_spec(base, axes, settings, chunks, _executor_threads(client))
    if store is None:
        arrays = empty_variables(spec.shape)
        _compute(spec, client, None, arrays, None, progress)
        return to_dataset(spec, arrays)
    with writer_lock(store):  # one writer per store (MapInUseError), as for regime maps
        if store.exists():
            group, stored_chunks, todo = open_for_resume(store, spec, chunks is not None)
            spec = replace(spec, chunks=stored_chunks)
        else:
            create_store(store, spec)
            group, todo = open_for_resume(store, spec, True)[0], None
        _compute(spec, client, ZarrSink(store, group), None, todo, progress)
    return open_atlas(store)


def _compute(spec: AtlasSpec, client: Any, sink: ZarrSink | None,
             arrays: dict[str, np.ndarray] | None, todo: list[tuple[int, ...]] | None,
             progress: bool) -> None:
    """Run the chunks ``todo`` (None: all) into the store's ``sink`` or into ``arrays``."""
    tasks = chunk_tasks(spec, todo)
    results = run_local(tasks) if client is None else _distributed(client, tasks)
    _drain(spec, results, sink, arrays, progress, sum(_cells(spec, t.slices) for t in tasks))


def _distributed(client: Any, tasks: list) -> Iterator:
    from .distributed import run_distributed

    return run_distributed(client, tasks)


def _cells(spec: AtlasSpec, slices: tuple[slice, ...]) -> int:
    return int(np.prod([s.stop - s.start for s in slices]))


def _drain(spec: AtlasSpec, results: Iterator, sink: ZarrSink | None,
           arrays: dict[str, np.ndarray] | None, progress: bool, n_todo: int) -> None:
    """Store each chunk as it arrives (in the store, or in ``arrays``)."""
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=spec.n_cells, initial=spec.n_cells - n_todo, unit="cell",
                   desc=f"atlas {spec.base.law} {'x'.join(map(str, spec.shape))}",
                   smoothing=0.1)
    try:
        for index, values in results:
            sl = chunk_slices(spec, index)
            if sink is not None:
                sink(sl, values)
            elif arrays is not None:
                for k, v in values.items():
                    arrays[k][sl] = v
            if bar is not None:
                bar.update(_cells(spec, sl))
    finally:
        if bar is not None:
            bar.close()
        close = getattr(results, "close", None)
        if close is not None:  # cancels a cluster's pending chunks on an error
            close()
