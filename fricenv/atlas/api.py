"""``fricenv.atlas``: validate, allocate or open the store, run the chunks, store them."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import xarray as xr

from ..calls import SweepInterrupted, sweep_signals
from ..cells import NOT_COMPUTED, STATUS_NOT_RUN, SweepSettings
from ..checks import check_bool, got
from ..jit import num_threads
from ..mapfile import writer_lock
from ..params import OscillatorParams
from .core import (
    AtlasSpec,
    ChunkTask,
    chunk_slices,
    chunk_tasks,
    empty_variables,
    make_spec,
    run_local,
)
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
        return num_threads()
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
    names (``u0, nu, eta, lam, V, xfk, xfs`` and the base's friction-law parameters:
    ``b1, b3`` for the paper's laws, ``vs, delta, cv`` for the exponential law) to 1-d
    grids, in the order of the
    result's dimensions. Each cell is measured exactly as :func:`fricenv.regime_map`
    measures it (same transient, window, periodicity test and label), bit for bit; with
    ``settings.lyapunov`` its largest Lyapunov exponent too (variable ``lyapunov``, NaN
    otherwise).

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

    Ctrl-C (or SIGTERM) stops the run within about a second, locally or on Dask, and
    raises :class:`~fricenv.SweepInterrupted` once every cell finished is kept: in the
    store with ``path`` (``results`` is None; the same call resumes), else in
    ``results``, the Dataset so far (cells not run hold the fill values).
    """
    progress = check_bool("progress", progress)
    _check_client(client)
    store = None if path is None else check_store_path(path)
    spec = make_spec(base, axes, settings, chunks, _executor_threads(client))
    if store is None:
        arrays = empty_variables(spec.shape)
        try:
            with sweep_signals():
                _compute(spec, client, _ChunkWriter(spec, None, arrays, {}), None, progress)
        except SweepInterrupted as stop:
            stop.results = to_dataset(spec, arrays)  # (the cells finished, the rest not)
            raise
        return to_dataset(spec, arrays)
    try:
        with writer_lock(store), sweep_signals():  # one writer per store (MapInUseError)
            if store.exists():
                group, stored_chunks, todo, part_done = open_for_resume(store, spec,
                                                                        chunks is not None)
                spec = replace(spec, chunks=stored_chunks)
            else:
                create_store(store, spec)
                group, todo, part_done = open_for_resume(store, spec, True)[0], None, {}
            _compute(spec, client,
                     _ChunkWriter(spec, ZarrSink(store, group), None, part_done), todo,
                     progress)
    except SweepInterrupted as stop:
        stop.results = None  # (the store holds the cells finished: open_atlas reads them)
        raise
    return open_atlas(store)


class _ChunkWriter:
    """Stores a chunk's variables in the store's sink or in ``arrays``; a chunk that a
    stopped run left part done (``part_done``: its stored variables) is merged first, the
    cells computed now (status not ``STATUS_NOT_RUN``) over the stored ones."""

    def __init__(self, spec: AtlasSpec, sink: ZarrSink | None,
                 arrays: dict[str, np.ndarray] | None,
                 part_done: dict[tuple[int, ...], dict[str, np.ndarray]]) -> None:
        self.spec, self.sink, self.arrays, self.part_done = spec, sink, arrays, part_done

    def __call__(self, index: tuple[int, ...], values: dict[str, np.ndarray]) -> int:
        """Store the chunk ``index``; the number of cells it brought."""
        new = values["status"] != STATUS_NOT_RUN
        if index in self.part_done:
            old = self.part_done[index]
            values = {k: np.where(new, v, old[k]) for k, v in values.items()}
        sl = chunk_slices(self.spec, index)
        if self.sink is not None:
            self.sink(sl, values)
        elif self.arrays is not None:
            for k, v in values.items():
                self.arrays[k][sl] = v
        return int(new.sum())

    def tasks(self, todo: list[tuple[int, ...]] | None) -> list[ChunkTask]:
        """The chunks ``todo`` (None: all) to run, a part-done one for its other cells."""
        tasks = chunk_tasks(self.spec, todo)
        return [replace(t, todo=self.part_done[t.index]["label"].ravel() == NOT_COMPUTED)
                if t.index in self.part_done else t for t in tasks]


def _compute(spec: AtlasSpec, client: Any, put: _ChunkWriter,
             todo: list[tuple[int, ...]] | None, progress: bool) -> None:
    """Run the chunks ``todo`` (None: all) and store them with ``put``."""
    tasks = put.tasks(todo)
    n_todo = sum(_cells(spec, t.slices) if t.todo is None else int(t.todo.sum())
                 for t in tasks)
    results = run_local(tasks) if client is None else _distributed(client, tasks)
    _drain(spec, results, put, progress, n_todo)


def _distributed(client: Any, tasks: list) -> Iterable:
    from .distributed import run_distributed

    return run_distributed(client, tasks)


def _cells(spec: AtlasSpec, slices: tuple[slice, ...]) -> int:
    return int(np.prod([s.stop - s.start for s in slices]))


def _drain(spec: AtlasSpec, results: Iterable, put: _ChunkWriter, progress: bool,
           n_todo: int) -> None:
    """Store each chunk as it arrives. On Ctrl-C (or SIGTERM, see
    :func:`fricenv.calls.sweep_signals`) the running chunks stop within about a second and
    their finished cells are stored too, before the interrupt propagates."""
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=spec.n_cells, initial=spec.n_cells - n_todo, unit="cell",
                   desc=f"atlas {spec.base.law} {'x'.join(map(str, spec.shape))}",
                   smoothing=0.1)
    storing = None  # (a chunk whose store a Ctrl-C may cut short: stored again)
    try:
        for index, values in results:
            storing = index, values
            n = put(index, values)
            storing = None
            if bar is not None:
                bar.update(n)
    except KeyboardInterrupt as stop:
        kept = [stop.results] if isinstance(stop, SweepInterrupted) and stop.results else []
        stop_run = getattr(results, "stop", None)  # (a cluster's run: its running chunks)
        kept += [storing] if storing is not None else []
        for index, values in kept + (stop_run() if stop_run is not None else []):
            put(index, values)
        if isinstance(stop, SweepInterrupted):
            raise
        # (Ctrl-C reached the client's own wait, not a kernel's: the same promise)
        raise SweepInterrupted(signum=signal.SIGINT) from None
    finally:
        if bar is not None:
            bar.close()
        cancel = getattr(results, "cancel", None)
        if cancel is not None:  # a cluster's chunks not run yet, on an error
            cancel()
