"""Parallel, resumable regime maps over the (u0, nu) plane.

Each grid cell is one independent run from the same initial state: a transient, then a
measurement window split into stroboscopic segments, all through the stats-only kernel
``core.advance`` (no trajectory is stored, so memory is O(grid) whatever the horizon). Cells
run on numba threads that each claim the next cell as soon as they are free (cells differ
in cost by orders of magnitude); a cell depends only on its own parameters, so the result is
bit-identical for any thread count, chunking, order or resumption. Every cell goes through
:func:`fricenv.cells.measure_cells`, as those of :func:`cell_statistics` and of an atlas do.

Time spans per cell (defaults of :class:`SweepSettings`)
---------------------------------------------------------
``T1 = 2 pi / eta`` (first tone) and the modulation period ``T_mod = T1 / dist(nu, Z)``
(:func:`modulation_period`: the slow tone's period for small ``nu``, the beat period near
``nu = 1``, ``T1`` for integer ``nu``; capped at ``100 T1``).

* transient = ``max(transient_min, transient_efolds * 2 / (lambda - b1), transient_periods
  * T_mod)`` = ``max(100, 50 / (lambda - b1), T_mod)``: a full modulation cycle and at least
  25 e-foldings of free slip near ``v = V`` (``lambda - b1`` is its damping; the term is
  dropped if it is not positive). 100 time units at the paper's ``lambda = 1/2``, Coulomb.
* window = ``max(window_min, window_periods * T_mod)`` = ``max(100, T_mod)``: every phase
  of the modulation is seen once. When ``nu`` is rational with denominator ``q <= q_max``
  the window is rounded up to whole common periods ``T_c = 2 pi q / eta`` and to at least
  ``n_strobe = 12`` of them, and the state is sampled after each one for
  :func:`fricenv.regimes.strobe_period`.
* integer ``nu`` (where the label depends on periodicity): a window that shows no period
  while its stroboscopic mismatch still shrinks (by half or more within the window) is
  repeated, up to ``lock_extensions = 3`` times, the failed ones counting as transient; the
  statistics are those of the last window. Quasi-periodic or chaotic cells stop at once.

``dist(nu, Z)`` is the distance from ``nu`` to the nearest integer.

Storage: ``RegimeMap.save`` (:mod:`fricenv.maps`) writes one ``.npz`` holding the arrays
and a JSON metadata string (parameters, settings, layout, regime names). With ``path=`` a
sweep saves at most every ``SAVE_EVERY_S`` seconds and when it ends or stops (atomically:
temporary file + ``os.replace``) and, when started again with the same arguments,
computes only the cells not yet marked done. A file made with other
parameters, grid, settings, time spans or measurement code (``ALGORITHM``) is refused.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from . import mapfile
from .calls import SweepInterrupted, sweep_signals
from .cells import CELL_KERNELS as CELL_KERNELS
from .cells import MAX_LOCK_EXTENSIONS as MAX_LOCK_EXTENSIONS
from .cells import MAX_PERIOD as MAX_PERIOD
from .cells import MAX_SEGMENTS as MAX_SEGMENTS
from .cells import (
    STATUS_NOT_RUN,
    CellPlan,
    CellResults,
    SweepSettings,
    cell_inputs,
    check_n_threads,
    measure_cells,
    plan_cells,
    settings_with,
)
from .cells import modulation_period as modulation_period
from .cells import run_cells as run_cells
from .checks import (
    check_bool,
    check_dict,
    check_int,
    got,
)
from .layout import N_STATS
from .maps import (
    _RESERVED_META,
    ALGORITHM,
    NOT_COMPUTED,
    RegimeMap,
    _check_axis,
    _map_path,
    _params_key,
)
from .maps import FORMAT as FORMAT
from .maps import FORMAT_VERSION as FORMAT_VERSION
from .maps import STAT_NAMES as STAT_NAMES
from .params import (
    OscillatorParams,
    resolve_law,
)
from .regimes import check_periodicity_settings

#: Most cells a regime map may have: its arrays take about 100 bytes a cell (10 GB at the
#: cap), allocated before the first cell runs; a larger grid is refused naming its size.
MAX_CELLS = 10**8
#: A map in progress is saved at most this often (seconds): each save rewrites the whole
#: file, and saving after every chunk made a 3 s map take 70 % longer. Its last chunks are
#: saved when it ends or stops on an exception; a killed process loses at most this much.
SAVE_EVERY_S = 10.0

def _as_params(params: OscillatorParams | str) -> OscillatorParams:
    if isinstance(params, OscillatorParams):
        return params
    if isinstance(params, str):
        return OscillatorParams.preset(resolve_law(params))
    raise TypeError(f"params must be OscillatorParams or a friction-law name, {got(params)}")


def _empty_map(params: OscillatorParams, u0: np.ndarray, nu: np.ndarray,
               settings: SweepSettings, q: np.ndarray, meta: dict) -> RegimeMap:
    shape = (u0.size, nu.size)
    return RegimeMap(
        params=params, u0=u0, nu=nu, settings=settings,
        labels=np.full(shape, NOT_COMPUTED, dtype=np.int8),
        stats=np.full(shape + (N_STATS,), np.nan),
        period=np.zeros(shape, dtype=np.int16),
        status=np.zeros(shape, dtype=np.int8),
        done=np.zeros(shape, dtype=bool),
        q=q.astype(np.int16), meta={**meta, "algorithm": ALGORITHM},
        lyapunov=np.full(shape, np.nan),
    )


def regime_map(params: OscillatorParams | str, u0: object, nu: object, *,
               settings: SweepSettings | None = None, path: str | os.PathLike | None = None,
               resume: bool = True, chunk_size: int | None = None,
               n_threads: int | None = None, progress: bool | None = None,
               callback: Callable[[RegimeMap, int], None] | None = None,
               meta: dict | None = None, **overrides: object) -> RegimeMap:
    """Classify every cell of the ``u0 x nu`` grid (axis 0: u0, axis 1: nu).

    ``params`` (or a friction-law name for the paper's defaults) fixes everything but the
    grid; both tones get amplitude ``u0`` and the second tone frequency ``nu * eta``
    (``params.u0`` and ``params.nu`` are replaced by the grid's; ``params.u1`` and ``u2``
    must be None, as they would be dropped). ``settings`` / keyword ``overrides`` set the
    transient, window and periodicity test (:class:`SweepSettings`); ``lyapunov=True``
    also measures each cell's largest Lyapunov exponent (``RegimeMap.lyapunov``). With
    ``path`` the map
    is saved at most every ``SAVE_EVERY_S`` seconds, after its last chunk and when the
    sweep stops on an exception (Ctrl-C, a callback's), and a run with the same
    arguments resumes from the file
    (``resume=False`` starts over; a file made with other arguments, or damaged, raises
    ``ValueError``; ``.npz`` is appended if missing; a ``path`` that cannot be written is
    refused before any cell runs). While it runs the sweep holds the map's writer lock
    (``<path>.lock``, released by the system if the process dies): a second sweep on the
    same path raises :class:`~fricenv.mapfile.MapInUseError` before it reads or writes
    anything. ``n_threads`` sets numba's thread count for the call; ``progress``
    shows a tqdm bar (default: when there are more than 2000 cells); ``callback(map,
    n_new)`` is called after each chunk is stored. ``meta`` adds free-form JSON-able
    entries under str keys to the metadata.
    """
    params = _as_params(params)
    if params.u1 is not None or params.u2 is not None:  # would be dropped without a word
        raise ValueError(f"params.u1 / params.u2 must be None in a regime map (both tones "
                         f"get amplitude u0 from the grid), got u1 = {params.u1!r}, "
                         f"u2 = {params.u2!r}")
    if path is not None:
        path = _map_path(path)
    check_dict("meta", meta)
    if callback is not None and not callable(callback):  # before any cell runs
        raise TypeError(f"callback must be callable, {got(callback)}")
    if meta:
        try:  # before any cell runs, as every save writes it: sorted among the map's own keys
            json.dumps({**dict.fromkeys(_RESERVED_META), **meta}, sort_keys=True)
        except (TypeError, ValueError) as e:
            raise TypeError(f"meta must hold JSON-able values under str keys: {e}") from None
    if meta and _RESERVED_META & set(meta):
        raise ValueError(f"meta must not set the reserved key(s) "
                         f"{sorted(_RESERVED_META & set(meta))}")
    u0 = _check_axis("u0", u0)
    nu = _check_axis("nu", nu)
    if u0.size * nu.size > MAX_CELLS:
        raise ValueError(f"a grid of u0 ({u0.size} values) x nu ({nu.size} values) has "
                         f"{u0.size * nu.size} cells, more than MAX_CELLS = {MAX_CELLS}")
    settings = settings_with(settings, overrides)
    check_periodicity_settings(settings.q_max, settings.m_max, settings.n_strobe)
    settings.method_code(params)  # ValueError for 'exact' on another law than Coulomb
    resume = check_bool("resume", resume)
    if progress is not None:
        check_bool("progress", progress)
    if chunk_size is not None:
        check_int("chunk_size", chunk_size, 1)
    if n_threads is not None:
        check_n_threads(n_threads)  # up front: a finished map never runs a cell to check it
    plan = plan_cells(params, nu, settings)
    # Checked before anything is written, on each nu's fastest cell (the scan step depends
    # on u0 only through whether it is 0).
    cell_inputs(params, {"u0": np.full(nu.size, np.max(np.abs(u0))), "nu": nu},
                settings).check()
    # One writer at a time: a second sweep on this path is refused while this one runs.
    with (mapfile.writer_lock(path) if path is not None else contextlib.nullcontext(),
          sweep_signals()):
        return _fill_map(_MapRequest(params, u0, nu, settings, plan, path, resume, chunk_size,
                                     n_threads, progress, callback, meta))


@dataclass(frozen=True)
class _MapRequest:
    """A :func:`regime_map` call once its arguments are checked: the map (plant, grid,
    settings and their cell plan) and how the sweep runs (file, chunks, threads, progress,
    callback, metadata), as :func:`regime_map` documents them."""

    params: OscillatorParams
    u0: np.ndarray
    nu: np.ndarray
    settings: SweepSettings
    plan: CellPlan
    path: Path | None
    resume: bool
    chunk_size: int | None
    n_threads: int | None
    progress: bool | None
    callback: Callable[[RegimeMap, int], None] | None
    meta: dict | None


def _fill_map(req: _MapRequest) -> RegimeMap:
    """The sweep of :func:`regime_map` once its arguments are checked (and, with a path,
    its writer lock held): resume or start the map, run the cells not done, save."""
    params, u0, nu, settings, plan = req.params, req.u0, req.nu, req.settings, req.plan
    path, meta, chunk_size, n_threads = req.path, req.meta, req.chunk_size, req.n_threads
    progress, callback = req.progress, req.callback
    rmap = None
    if path is not None:
        if req.resume and path.exists():
            rmap = RegimeMap.load(path)
            same = (rmap.meta.get("algorithm") == ALGORITHM
                    and _params_key(rmap.params) == _params_key(params)
                    and rmap.settings == settings
                    and np.array_equal(rmap.u0, u0) and np.array_equal(rmap.nu, nu)
                    and rmap.plan is not None
                    and all(np.array_equal(getattr(rmap.plan, f.name), getattr(plan, f.name))
                            for f in fields(CellPlan)))
            if not same:
                raise ValueError(f"{path} holds a map made with other parameters, grid or "
                                 "settings; remove it or pass resume=False")
    if rmap is None:
        rmap = _empty_map(params, u0, nu, settings, plan.q, meta or {})
        rmap.plan = plan
    elif meta:
        rmap.meta.update(meta)

    todo = np.flatnonzero(~rmap.done.ravel())
    n_nu = nu.size
    if chunk_size is None:
        chunk_size = int(min(2048, max(64, todo.size // 100)))
    show = (rmap.done.size > 2000) if progress is None else bool(progress)
    bar = None
    if show:
        from .progress import tqdm  # (its rate leaves out compile time)

        bar = tqdm(total=rmap.done.size, initial=int(rmap.done.sum()), unit="cell",
                   desc=f"regime map eta={params.eta:.4g} {params.law}", smoothing=0.1)
    last_save = time.perf_counter()
    unsaved = False
    try:
        for start in range(0, todo.size, chunk_size):
            idx = todo[start:start + chunk_size]
            iu, jn = np.divmod(idx, n_nu)
            t0 = time.perf_counter()
            try:
                cells = measure_cells(params, {"u0": u0[iu], "nu": nu[jn]}, settings,
                                      n_threads)
            except SweepInterrupted as stop:  # keep the chunk's finished cells, then stop
                _store_cells(rmap, iu, jn, stop.results)
                unsaved = path is not None
                raise
            finally:
                rmap.elapsed += time.perf_counter() - t0
            _store_cells(rmap, iu, jn, cells)
            unsaved = path is not None
            if path is not None and time.perf_counter() - last_save >= SAVE_EVERY_S:
                unsaved = False  # (a save that fails is not retried below)
                rmap.save(path)
                last_save = time.perf_counter()
            if bar is not None:
                bar.update(idx.size)
            if callback is not None:
                callback(rmap, int(idx.size))
    finally:
        if bar is not None:
            bar.close()
        # the last chunks, also when a callback, Ctrl-C or SIGTERM stops the sweep
        if unsaved and path is not None:
            rmap.labels[~rmap.done] = NOT_COMPUTED  # (a cell cut off between its writes)
            rmap.save(path)
    if path is not None and todo.size == 0 and not path.exists():
        rmap.save(path)
    return rmap


def _store_cells(rmap: RegimeMap, iu: np.ndarray, jn: np.ndarray, cells: CellResults
                 ) -> None:
    """Store the cells ``(iu[k], jn[k])`` of :func:`~fricenv.cells.measure_cells`' results
    that finished (all but those a stop left at ``STATUS_NOT_RUN``) in ``rmap`` and mark
    them done; each cell's values are written before it is marked, so a stop between two
    writes leaves no cell marked done without its values."""
    ok = cells.status != STATUS_NOT_RUN
    iu, jn = iu[ok], jn[ok]
    rmap.stats[iu, jn] = cells.stats[ok]
    rmap.status[iu, jn] = cells.status[ok]
    rmap.period[iu, jn] = cells.period[ok]
    rmap.lyapunov[iu, jn] = cells.lyapunov[ok]
    rmap.labels[iu, jn] = cells.labels[ok]
    rmap.done[iu, jn] = True


def cell_statistics(params: list[OscillatorParams], settings: SweepSettings | None = None,
                    n_threads: int | None = None, **overrides: object
                    ) -> tuple[np.ndarray, ...]:
    """Measure arbitrary parameter sets the way a map cell is measured.

    Returns ``(labels, stats, period, status)``, and the largest Lyapunov exponents fifth
    with ``lyapunov=True`` (as ``numpy.unique`` adds what its flags ask for), with one row
    per entry of ``params`` (a list,
    or any iterable, of :class:`OscillatorParams`); each entry's own ``eta``, ``nu`` and
    amplitudes are used. Each entry is measured by :func:`~fricenv.cells.measure_cells`, as
    a map or atlas cell is, so it gets the bits it gets there: with ``method="auto"`` a
    Coulomb entry runs ``"exact"`` and any other ``"event"``, whatever the other entries;
    ``"exact"`` needs every entry to be Coulomb.
    """
    if isinstance(params, (OscillatorParams, str)) or not isinstance(params, Iterable):
        raise TypeError(
            "params must be a list of OscillatorParams (wrap a single one in a list), "
            f"{got(params)}"
        )
    params = list(params)  # an iterator is read once, here
    if not params:
        raise ValueError("params is empty")
    for i, p in enumerate(params):
        if not isinstance(p, OscillatorParams):
            raise TypeError(
                f"params[{i}] must be an OscillatorParams, {got(p)}"
            )
    for i, p in enumerate(params):
        if p.friction != params[0].friction:
            raise ValueError(f"params[{i}] has friction={p.friction!r} where params[0] has "
                             f"{params[0].friction!r}: measure each friction law in its own "
                             "call")
    settings = settings_with(settings, overrides)
    check_periodicity_settings(settings.q_max, settings.m_max, settings.n_strobe)
    if settings.method == "exact":
        for i, p in enumerate(params):  # the method must suit every entry
            try:
                settings.method_code(p)
            except ValueError as e:
                raise ValueError(f"params[{i}]: {e}") from None
    values = {k: np.array([getattr(p, k) for p in params], dtype=np.float64)
              for k in ("nu", "eta", "lam", "V", "xfk", "xfs")}
    for name in ({n for p in params for n in p.law_values()}
                 if params[0].friction is not None else ("b1", "b3")):
        values[name] = np.array([getattr(p, name) for p in params], dtype=np.float64)
    values["u1"] = np.array([p.amp1 for p in params], dtype=np.float64)
    values["u2"] = np.array([p.amp2 for p in params], dtype=np.float64)
    try:
        with sweep_signals():
            cells = measure_cells(params[0], values, settings, n_threads)
    except SweepInterrupted as stop:
        cells = stop.results
        stop.results = _returned(cells, settings)
        raise
    return _returned(cells, settings)


def _returned(cells: CellResults, settings: SweepSettings) -> tuple[np.ndarray, ...]:
    """What ``cell_statistics`` returns: (labels, stats, period, status), and the Lyapunov
    exponents fifth when the settings ask for them."""
    out = (cells.labels, cells.stats, cells.period, cells.status)
    return (*out, cells.lyapunov) if settings.lyapunov else out
