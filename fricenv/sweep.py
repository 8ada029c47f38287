"""Parallel, resumable regime maps over the (u0, nu) plane.

Each grid cell is one independent run from the same initial state: a transient, then a
measurement window split into stroboscopic segments, all through the stats-only kernel
``core.advance`` (no trajectory is stored, so memory is O(grid) whatever the horizon). Cells
run on numba threads that each claim the next cell as soon as they are free (cells differ
in cost by orders of magnitude); a cell depends only on its own parameters, so the result is
bit-identical for any thread count, chunking, order or resumption.

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

Storage: ``RegimeMap.save`` writes one ``.npz`` holding the arrays and a JSON metadata
string (parameters, settings, layout, regime names). With ``path=`` a sweep saves after
every chunk (atomically: temporary file + ``os.replace``) and, when started again with the
same arguments, computes only the cells not yet marked done. A file made with other
parameters, grid, settings, time spans or measurement code (``ALGORITHM``) is refused.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import mapfile

# Cells (settings, plans, the checked parallel run) live in .cells and their kernels in
# .cell_kernels; their names stay importable from here.
from .cell_kernels import (  # noqa: F401
    CELL_KERNELS,
    _cells_kernel_event,
    _cells_kernel_exact,
    _converging,
    _event_cap,
    _run_cell_event,
    _run_cell_exact,
)
from .cells import (  # noqa: F401
    _INT_SETTINGS,
    _P_COLUMNS,
    MAX_LOCK_EXTENSIONS,
    MAX_PERIOD,
    MAX_SEGMENTS,
    STATUS_NOT_RUN,
    CellPlan,
    SweepSettings,
    _cell_rows,
    _check_cells,
    _check_rows,
    _count,
    _Threads,
    check_n_threads,
    modulation_period,
    plan_cells,
    run_cells,
)
from .checks import (
    check_bool,
    check_dict,
    check_finite_real,
    check_int,
    check_output_dir,
    check_path,
    got,
    real_array,
)
from .layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    N_STATS,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_SLIP,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
    ST_X_MAX,
    ST_X_MIN,
)
from .params import (
    P_W1,
    P_W2,
    PARAM_LIMIT,
    OscillatorParams,
    resolve_law,
)
from .regimes import Regime, classify

if TYPE_CHECKING:
    import xarray as xr
    from matplotlib.axes import Axes

FORMAT = "fricenv.regime_map"
FORMAT_VERSION = 1
# 12: time runs from 0 in each core call, and the transient skips the extrema (stats move
# by rounding); 13: slip excursions below v's rounding (x_fs ~ x_fk) end where their
# derivatives say, not at their start, and ties |f| = x_fs with |f| falling stick (such
# cells stopped as chattering); 14: a cell stuck all window long is STUCK, and a stick
# time is at most its window; 15: a cell whose motion runs away is DIVERGED
#: Version of the per-cell measurement; a stored map is resumed only if it matches.
ALGORITHM = 15
#: Most cells a regime map may have: its arrays take about 100 bytes a cell (10 GB at the
#: cap), allocated before the first cell runs; a larger grid is refused naming its size.
MAX_CELLS = 10**8
#: A map in progress is saved at most this often (seconds): each save rewrites the whole
#: file, and saving after every chunk made a 3 s map take 70 % longer. Its last chunks are
#: saved when it ends or stops on an exception; a killed process loses at most this much.
SAVE_EVERY_S = 10.0
#: Label of a cell that has not been computed yet (not a :class:`Regime`).
NOT_COMPUTED = -1

STAT_NAMES = ("duration", "stick_time", "n_stick", "n_slip", "n_reversal", "v_max", "v_min",
              "x_max", "x_min", "vr2_int", "n_steps")
assert len(STAT_NAMES) == N_STATS


# ------------------------------------------------------------------------------------------
@dataclass
class RegimeMap:
    """Labels and window statistics on a (u0, nu) grid; axis 0 is u0, axis 1 is nu."""

    params: OscillatorParams
    u0: np.ndarray
    nu: np.ndarray
    settings: SweepSettings
    labels: np.ndarray  # int8 (n_u0, n_nu), Regime values, NOT_COMPUTED if not done
    stats: np.ndarray  # float64 (n_u0, n_nu, N_STATS), layout ST_*
    period: np.ndarray  # int16: response period in common forcing periods, 0 none/untested
    status: np.ndarray  # int8: kernel status
    done: np.ndarray  # bool
    q: np.ndarray  # int16 (n_nu,): tested denominator of nu, 0 if untested
    elapsed: float = 0.0  # compute time spent so far, seconds (all sessions)
    meta: dict = field(default_factory=dict)
    plan: CellPlan | None = None  # per-nu time spans used (checked when resuming)

    # -- derived -----------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (self.u0.size, self.nu.size)

    @property
    def complete(self) -> bool:
        return bool(self.done.all())

    @property
    def stick_fraction(self) -> np.ndarray:
        d = self.stats[..., ST_DURATION]
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(d > 0, self.stats[..., ST_STICK_TIME] / np.where(d > 0, d, 1),
                            np.nan)

    @property
    def n_stick(self) -> np.ndarray:
        return self.stats[..., ST_N_STICK]

    @property
    def n_reversal(self) -> np.ndarray:
        return self.stats[..., ST_N_REVERSAL]

    @property
    def v_max(self) -> np.ndarray:
        return self.stats[..., ST_V_MAX]

    @property
    def v_min(self) -> np.ndarray:
        return self.stats[..., ST_V_MIN]

    @property
    def x_amplitude(self) -> np.ndarray:
        """Half the peak-to-peak displacement in the window."""
        return 0.5 * (self.stats[..., ST_X_MAX] - self.stats[..., ST_X_MIN])

    def plot(self, ax: Axes | None = None, *, boundaries: bool = True,
             title: str | None = None) -> Axes:
        """Draw the map on ``ax`` (u0 on x, nu on y, cells coloured by regime, the stick
        band's two boundaries) and return it; without ``ax``, on a new pyplot figure, so
        that a notebook shows it, as ``pandas`` and ``xarray`` plots do."""
        from . import plotting

        if ax is None:
            import matplotlib.pyplot as plt

            ax = plt.figure(figsize=(6.5, 4.6), layout="constrained").add_subplot()
        plotting.draw_regime_map(ax, self, boundaries=boundaries, title=title)
        return ax

    def counts(self) -> dict[str, int]:
        """Number of computed cells per regime name."""
        return {r.name: int(np.sum(self.labels == r)) for r in Regime}

    def to_xarray(self) -> xr.Dataset:
        """This map as an ``xarray.Dataset`` over ``(u0, nu)``, laid out as an atlas
        (:func:`fricenv.atlas`); needs the ``scale`` extra."""
        from .atlas.store import regime_map_dataset

        return regime_map_dataset(self)

    # -- storage -----------------------------------------------------------------------
    def metadata(self) -> dict:
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "algorithm": int(self.meta.get("algorithm", ALGORITHM)),
            "params": _params_key(self.params),
            "settings": asdict(self.settings),
            "stats_layout": list(STAT_NAMES),
            "regimes": {r.name: int(r) for r in Regime},
            "not_computed": NOT_COMPUTED,
            "axes": ["u0", "nu"],
            "elapsed_s": float(self.elapsed),
            "n_done": int(self.done.sum()),
            **{k: v for k, v in self.meta.items() if k not in _RESERVED_META},
        }

    def save(self, path: str | os.PathLike) -> Path:
        """Write atomically to ``path`` (``.npz`` appended if missing; arrays plus a JSON
        ``meta`` entry). ``TypeError`` / ``ValueError`` naming ``path`` before anything is
        written if it is not a file name or cannot be one (:func:`_map_path`);
        :class:`~fricenv.mapfile.MapInUseError` if a sweep in another process (or thread)
        is writing the map there."""
        path = _map_path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + f".tmp{os.getpid()}")
        plan = {} if self.plan is None else {
            f"plan_{f.name}": getattr(self.plan, f.name) for f in fields(CellPlan)}
        with mapfile.writer_lock(path):  # (a sweep's own saves share its lock)
            self._write(path, tmp, plan)
        return path

    def _write(self, path: Path, tmp: Path, plan: dict) -> None:
        try:
            with open(tmp, "wb") as fh:
                np.savez(fh, u0=self.u0, nu=self.nu, labels=self.labels, stats=self.stats,
                         period=self.period, status=self.status, done=self.done, q=self.q,
                         meta=np.array(json.dumps(self.metadata(), sort_keys=True)), **plan)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)  # a failed write leaves nothing behind

    @classmethod
    def load(cls, path: str | os.PathLike) -> RegimeMap:
        """Read a map written by :meth:`save` (``ValueError`` naming the file if it is not
        one, is damaged, incomplete or inconsistent, with the cause chained; the
        ``OSError`` of a path that cannot be opened: ``FileNotFoundError`` if there is
        none). ``.npz`` is appended if missing, as by :meth:`save`."""
        path = _with_npz(check_path("path", path))
        z = mapfile.read_npz(path)  # (ValueError for a damaged archive, cause chained)
        try:
            meta = json.loads(str(z["meta"][()]))
        except (KeyError, ValueError, RecursionError) as exc:
            raise mapfile.not_a_map(path, "no metadata") from exc
        if not isinstance(meta, dict):
            raise mapfile.not_a_map(path, f"its metadata is a {type(meta).__name__}, not a "
                                    "JSON object")
        if meta.get("format") != FORMAT or meta.get("version") != FORMAT_VERSION:
            raise ValueError(f"{path}: unsupported format {meta.get('format')!r} "
                             f"version {meta.get('version')!r}")
        missing = [k for k in _MAP_ARRAYS if k not in z]
        if missing:
            raise ValueError(f"{path} is not a complete regime map: no {missing}")
        names = [f"plan_{f.name}" for f in fields(CellPlan)]
        arrays = {k: z[k] for k in _MAP_ARRAYS}
        plan = CellPlan(*(z[n] for n in names)) if all(n in z for n in names) else None
        try:  # written by save, so anything else is a damaged or foreign file
            params = OscillatorParams(**meta["params"])
            settings = SweepSettings(**meta["settings"])
            elapsed = check_finite_real("elapsed_s", meta["elapsed_s"])
            algorithm = check_int("algorithm", meta.get("algorithm", 0))
            _check_map_arrays(arrays, plan)
        except (KeyError, TypeError, ValueError) as exc:
            what = f"no {exc}" if isinstance(exc, KeyError) else str(exc)
            raise ValueError(f"{path} is not a valid regime map: {what}") from exc
        extra = {k: v for k, v in meta.items()
                 if k not in ("format", "version", "params", "settings", "stats_layout",
                              "algorithm",
                              "regimes", "not_computed", "axes", "elapsed_s", "n_done")}
        extra["algorithm"] = algorithm
        return cls(params=params, settings=settings, elapsed=elapsed,
                   meta=extra, plan=plan, **arrays)


def _check_map_arrays(arrays: dict[str, np.ndarray], plan: CellPlan | None) -> None:
    """``ValueError`` unless a loaded map's arrays have the kinds and shapes :func:`_empty_map`
    gives them (a wrong-shape ``labels`` used to load, then fail a resume mid-sweep)."""
    u0 = _check_axis("u0", arrays["u0"])
    nu = _check_axis("nu", arrays["nu"])
    grid = (u0.size, nu.size)
    want = {"u0": ((u0.size,), "iuf"), "nu": ((nu.size,), "iuf"), "labels": (grid, "iu"),
            "stats": (grid + (N_STATS,), "f"), "period": (grid, "iu"),
            "status": (grid, "iu"), "done": (grid, "b"), "q": ((nu.size,), "iu")}
    if plan is not None:
        want.update({f"plan_{f.name}": ((nu.size,), "iuf") for f in fields(CellPlan)})
    for name, (shape, kinds) in want.items():
        a = (getattr(plan, name[5:]) if name.startswith("plan_") else arrays[name])
        if a.shape != shape or a.dtype.kind not in kinds:
            raise ValueError(f"{name} must be of shape {shape} and kind {kinds!r} for a "
                             f"{grid[0]} x {grid[1]} grid, got {a.shape} {a.dtype}")
    # ... and agree with each other, as a sweep leaves them (a resume trusts them: cells
    # marked done with no label were never recomputed, and the map called itself complete)
    for name, dtype in _MAP_DTYPES.items():
        if arrays[name].dtype != dtype:
            raise ValueError(f"{name} must be {np.dtype(dtype)}, got {arrays[name].dtype}")
    labels, done = arrays["labels"], arrays["done"]
    bad = ~np.isin(labels, [NOT_COMPUTED, *(int(r) for r in Regime)])
    if bad.any():
        raise ValueError(f"labels holds {int(labels[bad][0])}, neither a Regime value nor "
                         f"NOT_COMPUTED ({NOT_COMPUTED})")
    if np.any(done == (labels == NOT_COMPUTED)):
        raise ValueError("labels and done disagree: a cell is done exactly when it has a "
                         "Regime label")
    if plan is not None and not np.array_equal(arrays["q"], plan.q):
        raise ValueError(f"q {arrays['q'].tolist()} differs from the plan's "
                         f"{plan.q.tolist()}")


def _with_npz(p: Path) -> Path:
    return p if p.suffix == ".npz" or p.name in ("", ".", "..") else p.with_name(p.name + ".npz")


def _map_path(path: object) -> Path:
    """Where a map is saved: ``path`` with ``.npz`` appended if missing. ``TypeError`` for a
    non-path, ``ValueError`` naming ``path`` for a name that is no file ('', '.', '..') or
    a file that cannot be written (a folder there, a file among its parents), so that a
    sweep fails before its first chunk rather than at the first save."""
    p = check_path("path", path)
    if p.name in ("", ".", ".."):
        raise ValueError(f"path must name a file, got {str(path)!r}")
    p = _with_npz(p)
    if p.is_dir():  # (checks.check_output_file, with the file's name in the message)
        raise ValueError(f"path {str(p)!r} is a folder, not a file")
    check_output_dir(f"path {str(p)!r} needs the folder", p.parent)
    return p


#: Arrays a saved map holds besides its metadata.
_MAP_ARRAYS = ("u0", "nu", "labels", "stats", "period", "status", "done", "q")
#: Their exact types where ``_empty_map`` fixes one.
_MAP_DTYPES = {"labels": np.int8, "period": np.int16, "status": np.int8, "done": np.bool_,
               "q": np.int16}

#: Metadata keys written by :meth:`RegimeMap.metadata` itself; user ``meta`` cannot set them.
_RESERVED_META = frozenset({"format", "version", "algorithm", "params", "settings",
                            "stats_layout", "regimes", "not_computed", "axes", "elapsed_s",
                            "n_done"})


def _params_key(params: OscillatorParams) -> dict:
    """Parameters that define a map (the grid replaces u0, u1, u2 and nu)."""
    d = params.to_dict()
    d.update(u0=0.0, nu=1.0, u1=None, u2=None)
    return d


def _check_axis(name: str, a: object) -> np.ndarray:
    """A grid axis as a 1-d float array: ``TypeError`` unless made of real numbers (None
    would become NaN, strings such as ``"0.5"`` would be parsed), ``ValueError`` for a
    ragged, 2-d, empty, non-finite or negative one."""
    arr = real_array(a, f"{name} must be an array of real numbers")
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-d, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} grid is empty")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} grid contains NaN or infinite values")
    if np.any(arr < 0):
        raise ValueError(f"{name} grid must be >= 0")
    if np.any(arr > PARAM_LIMIT):
        raise ValueError(f"{name} grid must lie within {PARAM_LIMIT:g} (as every parameter), "
                         f"got {float(arr.max())!r}")
    values, counts = np.unique(arr, return_counts=True)
    if np.any(counts > 1):  # a cell computed twice, and a map the plots cannot draw
        k = int(np.argmax(counts > 1))
        raise ValueError(f"{name} grid must not repeat a value, got {float(values[k])!r} "
                         f"{int(counts[k])} times")
    return arr


def _settings(settings: SweepSettings | None, overrides: dict) -> SweepSettings:
    """The settings of a sweep: ``settings`` (default: the defaults) with ``overrides``."""
    known = {f.name for f in fields(SweepSettings)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ValueError(f"unknown setting(s) {unknown}; expected some of {sorted(known)}")
    if settings is None:
        return SweepSettings(**overrides)
    if not isinstance(settings, SweepSettings):
        raise TypeError(
            "settings must be a fricenv.SweepSettings or None (single settings can also be "
            f"passed as keyword arguments), {got(settings)}"
        )
    if overrides:
        return SweepSettings(**{**asdict(settings), **overrides})
    return settings


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
    transient, window and periodicity test (:class:`SweepSettings`). With ``path`` the map
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
    settings = _settings(settings, overrides)
    method = settings.method_code(params)
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
    base = params.to_array()
    fastest = _cell_rows(base, np.full(nu.size, np.max(np.abs(u0))), plan.nu_exact)
    _check_cells(fastest, plan.t_transient, plan.t_segment, plan.n_segment, plan.tries)
    # One writer at a time: a second sweep on this path is refused while this one runs.
    with mapfile.writer_lock(path) if path is not None else contextlib.nullcontext():
        return _fill_map(params, u0, nu, settings, plan, method, path=path, resume=resume,
                         chunk_size=chunk_size, n_threads=n_threads, progress=progress,
                         callback=callback, meta=meta)


def _fill_map(params: OscillatorParams, u0: np.ndarray, nu: np.ndarray,
              settings: SweepSettings, plan: CellPlan, method: int, *, path: Path | None,
              resume: bool, chunk_size: int | None, n_threads: int | None,
              progress: bool | None, callback: Callable[[RegimeMap, int], None] | None,
              meta: dict | None) -> RegimeMap:
    """The sweep of :func:`regime_map` once its arguments are checked (and, with ``path``,
    its writer lock held): resume or start the map, run the cells not done, save."""
    base = params.to_array()
    rmap = None
    if path is not None:
        if resume and path.exists():
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
        from tqdm.auto import tqdm

        bar = tqdm(total=rmap.done.size, initial=int(rmap.done.sum()), unit="cell",
                   desc=f"regime map eta={params.eta:.4g} {params.law}", smoothing=0.1)
    last_save = time.perf_counter()
    unsaved = False
    try:
        for start in range(0, todo.size, chunk_size):
            idx = todo[start:start + chunk_size]
            iu, jn = np.divmod(idx, n_nu)
            P = _cell_rows(base, u0[iu], plan.nu_exact[jn])
            t0 = time.perf_counter()
            st, status, period = run_cells(P, plan.t_transient[jn], plan.t_segment[jn],
                                           plan.n_segment[jn], plan.tries[jn], settings,
                                           method, n_threads)
            rmap.elapsed += time.perf_counter() - t0
            rmap.stats[iu, jn] = st
            rmap.status[iu, jn] = status
            rmap.period[iu, jn] = period
            rmap.labels[iu, jn] = classify(st[:, ST_N_STICK], st[:, ST_STICK_TIME],
                                           st[:, ST_N_REVERSAL], nu[jn], plan.q[jn], period,
                                           status, st[:, ST_N_SLIP])
            rmap.done[iu, jn] = True
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
        # the last chunks, also when a callback or Ctrl-C stops the sweep
        if unsaved and path is not None:
            rmap.labels[~rmap.done] = NOT_COMPUTED  # (a chunk cut off between its writes)
            rmap.save(path)
    if path is not None and todo.size == 0 and not path.exists():
        rmap.save(path)
    return rmap


def cell_statistics(params: list[OscillatorParams], settings: SweepSettings | None = None,
                    n_threads: int | None = None, **overrides: object
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Measure arbitrary parameter sets the way a map cell is measured.

    Returns ``(labels, stats, period, status)`` with one row per entry of ``params`` (a list,
    or any iterable, of :class:`OscillatorParams`); each entry's own ``eta``, ``nu`` and
    amplitudes are used. With ``method="auto"`` a list of Coulomb entries runs ``"exact"``
    and any other list ``"event"``; ``"exact"`` needs every entry to be Coulomb.
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
    settings = _settings(settings, overrides)
    coul = {p.is_coulomb for p in params}
    if settings.method == "auto":
        method = METHOD_EXACT if coul == {True} else METHOD_EVENT
    else:
        for i, p in enumerate(params):  # the method must suit every entry
            try:
                method = settings.method_code(p)
            except ValueError as e:
                raise ValueError(f"params[{i}]: {e}") from None
    rows, tt, ts, ns, qs, nus, tr = [], [], [], [], [], [], []
    for p in params:
        plan = plan_cells(p, np.array([p.nu]), settings)
        P = p.to_array()
        P[P_W2] = plan.nu_exact[0] * P[P_W1]
        rows.append(P)
        tt.append(plan.t_transient[0])
        ts.append(plan.t_segment[0])
        ns.append(plan.n_segment[0])
        qs.append(plan.q[0])
        tr.append(plan.tries[0])
        nus.append(p.nu)
    qs_a = np.array(qs)
    st, status, period = run_cells(np.array(rows), np.array(tt), np.array(ts), np.array(ns),
                                   np.array(tr), settings, method, n_threads)
    labels = classify(st[:, ST_N_STICK], st[:, ST_STICK_TIME], st[:, ST_N_REVERSAL],
                      np.array(nus), qs_a, period, status, st[:, ST_N_SLIP])
    return np.asarray(labels), st, period, status
