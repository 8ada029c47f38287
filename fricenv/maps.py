"""A regime map as a result: the :class:`RegimeMap` record, its file and its checks.

:func:`fricenv.regime_map` (in :mod:`fricenv.sweep`) computes the cells; this module holds
what a map is once computed: the labels, window statistics and plan on a (u0, nu) grid,
how it is written (atomically, under the map's writer lock) and read back (every array
checked against the others, a damaged archive named in a ``ValueError``; see
:mod:`fricenv.mapfile`), and the version of the per-cell measurement that decides
whether a stored map may be resumed.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import layout, mapfile
from .cells import NOT_COMPUTED, CellPlan, SweepSettings
from .checks import check_finite_real, check_int, check_output_dir, check_path, real_array
from .layout import (
    N_STATS,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
    ST_VR2_INT,
    ST_X_MAX,
    ST_X_MIN,
    STATUS_OK,
)
from .params import PARAM_LIMIT, OscillatorParams
from .regimes import Regime, classify_stats

if TYPE_CHECKING:
    from matplotlib.axes import Axes

FORMAT = "fricenv.regime_map"
FORMAT_VERSION = 1
#: Version of the per-cell measurement; a stored map is resumed only if it matches
#: (CHANGELOG.md says what each version changed).
ALGORITHM = 16

STAT_NAMES = ("duration", "stick_time", "n_stick", "n_slip", "n_reversal", "v_max", "v_min",
              "x_max", "x_min", "vr2_int", "n_steps")
assert len(STAT_NAMES) == N_STATS


# ------------------------------------------------------------------------------------------
def stick_fractions(stats: np.ndarray) -> np.ndarray:
    """The stick fraction (stuck time over time covered) of each row of statistics
    ``stats`` (..., N_STATS), as ``cell_statistics`` and the maps return them; NaN where
    no time was covered."""
    d = stats[..., ST_DURATION]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(d > 0, stats[..., ST_STICK_TIME] / np.where(d > 0, d, 1), np.nan)


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
    #: float64 (n_u0, n_nu): largest Lyapunov exponent (``SweepSettings.lyapunov``), NaN
    #: where not measured
    lyapunov: np.ndarray = None  # type: ignore[assignment]  # (filled in below)

    def __post_init__(self) -> None:
        if self.lyapunov is None:
            self.lyapunov = np.full(self.labels.shape, np.nan)

    # -- derived -----------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (self.u0.size, self.nu.size)

    @property
    def complete(self) -> bool:
        return bool(self.done.all())

    @property
    def stick_fraction(self) -> np.ndarray:
        return stick_fractions(self.stats)

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
             title: str | None = None, legend: bool = True) -> Axes:
        """Draw the map on ``ax`` (u0 on x, nu on y, cells coloured by regime, the stick
        band's two boundaries, a legend of the regimes drawn) and return it; without
        ``ax``, on a new pyplot figure, so that a notebook shows it, as ``pandas`` and
        ``xarray`` plots do. ``title``: default, the law and eta."""
        from . import plotting

        if ax is None:
            import matplotlib.pyplot as plt

            ax = plt.figure(figsize=(8.0, 4.6), layout="constrained").add_subplot()
        plotting.draw_regime_map(ax, self, boundaries=boundaries, legend=legend,
                                 title=plotting.map_title(self) if title is None else title)
        return ax

    def counts(self) -> dict[str, int]:
        """Number of computed cells per regime name."""
        return {r.name: int(np.sum(self.labels == r)) for r in Regime}

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
        ``meta`` entry; a symlink there keeps pointing to the file, which is replaced).
        ``TypeError`` / ``ValueError`` naming ``path`` before anything is
        written if it is not a file name or cannot be one (:func:`_map_path`);
        :class:`~fricenv.mapfile.MapInUseError` if a sweep in another process (or thread)
        is writing the map there."""
        path = _map_path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        # A symlink stays one: the file it points to is the one replaced (replacing the
        # link itself turned it into a regular file, and the target went stale).
        target = Path(os.path.realpath(path))
        target.parent.mkdir(parents=True, exist_ok=True)  # (a link to a folder not made)
        tmp = target.with_name(target.name + f".tmp{os.getpid()}")
        plan = {} if self.plan is None else {
            f"plan_{f.name}": getattr(self.plan, f.name) for f in fields(CellPlan)}
        with mapfile.writer_lock(target):  # (a sweep's own saves share its lock)
            self._write(target, tmp, plan)
        return path

    def _write(self, path: Path, tmp: Path, plan: dict) -> None:
        try:
            with open(tmp, "wb") as fh:
                np.savez(fh, u0=self.u0, nu=self.nu, labels=self.labels, stats=self.stats,
                         period=self.period, status=self.status, done=self.done, q=self.q,
                         lyapunov=self.lyapunov,
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
        none). ``.npz`` is appended if missing, as by :meth:`save`, unless only the file
        as named exists (``m.npy``: read, and named in the error if it is no map)."""
        given = check_path("path", path)
        path = _with_npz(given)
        if path != given and not path.exists() and given.is_file():
            path = given
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
        # (maps saved before the exponent was measured have none: NaN, not measured)
        arrays["lyapunov"] = z["lyapunov"] if "lyapunov" in z else np.full(
            arrays["labels"].shape, np.nan)
        plan = CellPlan(*(z[n] for n in names)) if all(n in z for n in names) else None
        try:  # written by save, so anything else is a damaged or foreign file
            params = OscillatorParams(**meta["params"])
            settings = SweepSettings(**meta["settings"])
            elapsed = check_finite_real("elapsed_s", meta["elapsed_s"])
            algorithm = check_int("algorithm", meta.get("algorithm", 0))
            _check_map_arrays(arrays, plan)
            if algorithm == ALGORITHM:  # (older maps were labelled by older rules)
                _check_labels(arrays)
        except (KeyError, TypeError, ValueError) as exc:
            what = f"no {exc}" if isinstance(exc, KeyError) else str(exc)
            raise mapfile.not_a_map(path, what) from exc
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
            "status": (grid, "iu"), "done": (grid, "b"), "q": ((nu.size,), "iu"),
            "lyapunov": (grid, "f")}
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
    _check_cell_values(arrays)


#: Every status a cell may have (``layout.STATUS_*``).
KNOWN_STATUSES = frozenset(v for k, v in vars(layout).items()
                           if k.startswith("STATUS_") and isinstance(v, int))


def _check_cell_values(arrays: dict[str, np.ndarray]) -> None:
    """``ValueError`` naming the array, the first bad cell and its value unless every
    value is one a sweep writes: a known status, a period and a q >= 0, and finite
    statistics in a cell computed with status OK (vr2_int may be NaN: not measured). A
    resume keeps every done cell as it is, so a file that passes its checksums but holds
    impossible values is refused here, as a damaged one is."""
    u0, nu = arrays["u0"], arrays["nu"]

    def refuse(name: str, bad: np.ndarray, value: np.ndarray, why: str) -> None:
        i = tuple(int(k) for k in np.argwhere(bad)[0])
        if len(i) == 1:
            at = f"nu[{i[0]}] = {float(nu[i[0]])!r}"
        else:
            at = f"cell {i[:2]} (u0 = {float(u0[i[0]])!r}, nu = {float(nu[i[1]])!r})"
        if len(i) == 3:
            at += f", statistic {STAT_NAMES[i[2]]!r}"
        raise ValueError(f"{name} holds {value[i].item()!r} at {at}: {why}")

    status, period, q, stats = arrays["status"], arrays["period"], arrays["q"], arrays["stats"]
    bad = ~np.isin(status, sorted(KNOWN_STATUSES))
    if bad.any():
        refuse("status", bad, status, f"a status is one of {sorted(KNOWN_STATUSES)} "
               "(layout.STATUS_*)")
    for name, a in (("period", period), ("q", q)):
        if np.any(a < 0):
            refuse(name, a < 0, a, f"{name} is >= 0")
    ok = arrays["done"] & (status == STATUS_OK)
    # (a sweep does not integrate (v - V)^2: NaN there means not measured)
    measured = np.where(np.arange(N_STATS) == ST_VR2_INT, ~np.isnan(stats), True)
    bad = ok[..., None] & measured & ~np.isfinite(stats)
    if bad.any():
        refuse("stats", bad, stats, "a cell computed with status OK has finite statistics")


def _check_labels(arrays: dict[str, np.ndarray]) -> None:
    """``ValueError`` naming the first cell whose label is not the one its own statistics,
    period and status give (:func:`~fricenv.regimes.classify_stats`, the rule every sweep
    labels by): the checksums cover the bytes, not their sense, and a resume keeps every
    done cell's label as it is."""
    done = arrays["done"]
    if not done.any():
        return
    cols = np.broadcast_to(np.arange(done.shape[1]), done.shape)[done]
    want = classify_stats(arrays["stats"][done], arrays["nu"][cols], arrays["q"][cols],
                          arrays["period"][done], arrays["status"][done])
    have = arrays["labels"][done]
    bad = np.flatnonzero(want != have)
    if bad.size:
        k = int(bad[0])
        i, j = (int(v) for v in np.argwhere(done)[k])
        raise ValueError(
            f"labels holds {Regime(int(have[k])).name} at cell ({i}, {j}) (u0 = "
            f"{float(arrays['u0'][i])!r}, nu = {float(arrays['nu'][j])!r}), where the cell's "
            f"statistics give {Regime(int(want[k])).name} ({bad.size} cells disagree)")


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


def _params_key(params: OscillatorParams) -> dict:
    """Parameters that define a map (the grid replaces u0, u1, u2 and nu)."""
    d = params.to_dict()
    d.update(u0=0.0, nu=1.0, u1=None, u2=None)
    return d
