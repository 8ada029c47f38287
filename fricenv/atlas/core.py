"""The atlas's grid, its validation, its chunk plan and the computation of one chunk.

Nothing here imports Dask, Zarr or xarray: a worker needs only this module, numpy and the
simulator, and the local path runs on it directly. A chunk is a rectangular block of the
grid; it is the unit of work (one task, all its cells in one numba call per method), of
storage (one Zarr chunk per variable) and of resumption.

A chunk's cells are measured by :func:`fricenv.cells.measure_cells`, the function that
measures the cells of :func:`fricenv.regime_map` and :func:`fricenv.cell_statistics`: the
same parameter rows, time spans (elementwise in ``nu``, so a chunk's slice of the ``nu``
grid gets the whole grid's spans), kernels and labels. A cell depends only on its own
parameters, so the atlas is bit-identical to the regime map (and to ``cell_statistics``)
for any chunking, order, worker or resumption.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..calls import SweepInterrupted
from ..cells import (
    NOT_COMPUTED,
    STATUS_NOT_RUN,  # (the stored fill value of a cell that has not run)
    SweepSettings,
    cell_inputs,
    measure_cells,
    plan_cells,
    settings_with,
)
from ..checks import check_int, got, real_array
from ..friction import OWNER
from ..layout import (
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
)
from ..params import (
    PARAM_LIMIT,
    OscillatorParams,
    resolve_law,
)
from ..regimes import check_periodicity_settings

#: Parameters an atlas may sweep: every numeric field of OscillatorParams that sets a cell
#: (u1 and u2 are not: both tones get amplitude u0, as in a regime map).
AXIS_FIELDS = ("u0", "nu", "eta", "lam", "V", "xfk", "xfs", *OWNER)

#: The variables of an atlas, their dtype and the value of a cell not computed yet. The
#: label is written last for each chunk, so a stored label marks its chunk complete.
VARIABLES: dict[str, tuple[str, float]] = {
    "stick_fraction": ("float64", math.nan),
    "n_stick": ("float64", math.nan),
    "n_reversal": ("float64", math.nan),
    "v_min": ("float64", math.nan),
    "v_max": ("float64", math.nan),
    "period": ("int16", 0),
    "status": ("int8", STATUS_NOT_RUN),
    "lyapunov": ("float64", math.nan),
    "label": ("int8", NOT_COMPUTED),
}

#: Default chunk sizes: about this many chunks per thread of the executor, so that a chunk
#: of stiff cells finishing last leaves the other threads idle for a small share of the
#: run, ...
CHUNKS_PER_THREAD = 32
#: ... but no fewer cells per chunk than this (each chunk costs a task, a plan and a few
#: file writes, about a millisecond) ...
MIN_CHUNK_CELLS = 256
#: ... nor more (the client holds a few chunks at once: 16384 cells are about 0.7 MB).
MAX_CHUNK_CELLS = 16384
#: Most cells an atlas may have. 10^10 cells take a store of about 200 GB and 140
#: core-hours at the fastest law's 20,000 cells/s (2,500 for the Stribeck law); a larger
#: grid (three axes of 10^4 values, say) is far likelier a slip than a plan, and is
#: refused from the axes' lengths alone, before any work per value.
MAX_CELLS = 10**10
#: Rows checked at once for the scan-step bound before any cell runs (memory bound).
_CHECK_BATCH = 1 << 18


@dataclass(frozen=True)
class AtlasSpec:
    """A validated atlas: what every cell is, and how the grid is cut into chunks."""

    base: OscillatorParams
    axes: dict[str, np.ndarray]  # ordered: the dims of the result
    settings: SweepSettings
    chunks: tuple[int, ...]  # chunk length along each axis

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.axes)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(a.size for a in self.axes.values())

    @property
    def n_cells(self) -> int:
        return math.prod(self.shape)

    @property
    def chunk_grid(self) -> tuple[int, ...]:
        """Number of chunks along each axis."""
        return tuple(-(-n // c) for n, c in zip(self.shape, self.chunks, strict=True))

    def base_key(self) -> dict:
        """The base parameters that define the cells: swept fields are the grid's."""
        d = self.base.to_dict()
        for name in self.axes:
            d[name] = None
        return d


@dataclass(frozen=True)
class ChunkTask:
    """One chunk: its index in the chunk grid and everything a worker needs to run it.

    Small (grid slices, not parameter rows) so that a scheduler ships it cheaply.
    """

    index: tuple[int, ...]
    slices: tuple[slice, ...]
    base: OscillatorParams
    grids: dict[str, np.ndarray]  # this chunk's slice of each axis
    settings: SweepSettings
    cost: float  # estimated relative cost (simulated time), for scheduling order
    # the cells to run (flat, C order; None: all): a chunk that a stop left part-done
    # runs the rest only
    todo: np.ndarray | None = None


# -- validation ------------------------------------------------------------------------
def _check_base(base: object) -> OscillatorParams:
    if isinstance(base, str):
        return OscillatorParams.preset(resolve_law(base))
    if not isinstance(base, OscillatorParams):
        raise TypeError(f"base must be OscillatorParams or a friction-law name, {got(base)}")
    if base.u1 is not None or base.u2 is not None:  # would be dropped without a word
        raise ValueError(f"base.u1 / base.u2 must be None in an atlas (both tones get "
                         f"amplitude u0), got u1 = {base.u1!r}, u2 = {base.u2!r}")
    return base


def _axis_array(name: str, grid: object) -> np.ndarray:
    """One axis as a 1-d float array (its values not looked at yet)."""
    arr = real_array(grid, f"axes[{name!r}] must be a 1-d array of real numbers")
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise ValueError(f"axes[{name!r}] must be 1-d, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"axes[{name!r}] is empty")
    return arr


def _check_size(shape: tuple[int, ...]) -> None:
    """``ValueError`` for a grid of more than ``MAX_CELLS`` cells, from its shape alone."""
    if math.prod(shape) > MAX_CELLS:
        raise ValueError(f"an atlas of shape {shape} has {math.prod(shape):.3g} cells, more "
                         f"than MAX_CELLS = {MAX_CELLS:.3g}: split it into several atlases")


def _check_grid(name: str, arr: np.ndarray, base: OscillatorParams) -> None:
    """Each value of one axis valid for its field alone, and none repeated."""
    bad = ~(np.abs(arr) <= PARAM_LIMIT)  # NaN, inf, huge: each named by OscillatorParams
    rules = {"u0": arr >= 0, "nu": arr >= 0, "eta": arr > 0, "lam": arr >= 0,
             "xfk": arr >= 0}
    bad |= ~rules.get(name, np.ones(arr.size, dtype=bool))
    if bad.any():
        value = float(arr[int(np.argmax(bad))])
        try:
            base.replace(**{name: value, **({"xfs": PARAM_LIMIT} if name == "xfk" else {})})
        except ValueError as exc:
            raise ValueError(f"axes[{name!r}]: {exc}") from None
        raise ValueError(f"axes[{name!r}] holds the invalid value {value!r}")  # (unreached)
    values, counts = np.unique(arr, return_counts=True)
    if np.any(counts > 1):  # a cell computed twice, and a slice the plots cannot draw
        k = int(np.argmax(counts > 1))
        raise ValueError(f"axes[{name!r}] must not repeat a value, got {float(values[k])!r} "
                         f"{int(counts[k])} times")


def _check_axes(axes: object, base: OscillatorParams) -> dict[str, np.ndarray]:
    if not isinstance(axes, Mapping):
        raise TypeError(f"axes must be a mapping from parameter names to 1-d grids, e.g. "
                        f"{{'u0': ..., 'nu': ...}}, {got(axes)}")
    if not axes:
        raise ValueError("axes is empty: give at least one parameter and its grid")
    out = {}
    for name, grid in axes.items():
        if name not in AXIS_FIELDS:
            raise ValueError(f"axes: {name!r} is not a parameter an atlas can sweep; "
                             f"expected some of {list(AXIS_FIELDS)}")
        out[name] = _axis_array(name, grid)
    _check_size(tuple(a.size for a in out.values()))  # (before any work per value)
    for name, arr in out.items():
        _check_grid(name, arr, base)
    _check_friction_levels(out, base)
    return out


def _check_friction_levels(axes: dict[str, np.ndarray], base: OscillatorParams) -> None:
    """Every grid point is a cell, so the smallest static level meets the largest kinetic
    one somewhere: refuse ``xfs < xfk`` there, before any cell runs."""
    xfs = axes.get("xfs", np.array([base.xfs]))
    xfk = axes.get("xfk", np.array([base.xfk]))
    if xfs.min() < xfk.max():
        field = "xfs" if "xfs" in axes else "xfk"
        value = float(xfs.min() if field == "xfs" else xfk.max())
        gives = "" if field == "xfs" else f"{field} = {value!r} gives "
        raise ValueError(f"axes[{field!r}]: {gives}xfs = "
                         f"{float(xfs.min())!r} < xfk = {float(xfk.max())!r} at a grid "
                         "point (every combination of the axes is a cell); the static "
                         "friction level must be >= the kinetic one")


def _plan_groups(spec_axes: dict[str, np.ndarray], base: OscillatorParams
                 ) -> Iterator[tuple[dict[str, float], OscillatorParams]]:
    """Each distinct combination of the fields the time spans depend on, and its params."""
    names = [k for k in base.plan_fields() if k in spec_axes]
    for values in itertools.product(*(spec_axes[k] for k in names)):
        fixed = {k: float(v) for k, v in zip(names, values, strict=True)}
        yield fixed, base.replace(**fixed)


def _check_cells(axes: dict[str, np.ndarray], base: OscillatorParams,
                 settings: SweepSettings) -> None:
    """Run every check the kernel would, before any cell runs: methods, windows (in
    ``plan_cells``), parameter rows and the scan-step bound, on the grid with u0 at its
    largest (the scan step depends on u0 only through whether it is 0)."""
    b1 = axes.get("b1", np.array([base.b1]))
    b3 = axes.get("b3", np.array([base.b3]))
    # (only whether some cell is not Coulomb matters: method 'exact' refuses it; the
    # largest coefficients make such a cell where one exists)
    settings.method_code(base.replace(b1=float(b1[np.argmax(np.abs(b1))]),
                                      b3=float(b3[np.argmax(np.abs(b3))])))
    nu = axes.get("nu", np.array([base.nu]))
    for eta in axes.get("eta", [base.eta]):  # (a plan is refused for its eta and nu alone)
        try:
            plan_cells(base.replace(eta=float(eta)), nu, settings)
        except ValueError as exc:
            where = f" (at eta = {float(eta)!r})" if "eta" in axes else ""
            raise ValueError(f"{exc}{where}") from None
    reduced = dict(axes)
    u0 = axes.get("u0", np.array([base.u0]))
    reduced["u0"] = np.array([u0.max()])
    names = list(reduced)
    shape = tuple(reduced[k].size for k in names)
    n = math.prod(shape)
    for start in range(0, n, _CHECK_BATCH):
        flat = np.arange(start, min(n, start + _CHECK_BATCH))
        values = dict(zip(names, (reduced[k][i] for k, i in
                                  zip(names, np.unravel_index(flat, shape), strict=True)),
                          strict=True))
        cell_inputs(base, values, settings).check()


def auto_chunks(shape: Sequence[int], target: int) -> tuple[int, ...]:
    """Chunk lengths with at most ``target`` cells: halve the longest chunk side until the
    chunk is small enough, so chunks stay near-cubes (any 2-d slice reads few of them)."""
    chunks = list(shape)
    while math.prod(chunks) > target and max(chunks) > 1:
        k = int(np.argmax(chunks))
        chunks[k] = -(-chunks[k] // 2)
    return tuple(chunks)


def default_chunk_target(n_cells: int, n_threads: int) -> int:
    return int(min(MAX_CHUNK_CELLS,
                   max(MIN_CHUNK_CELLS, n_cells // max(1, n_threads * CHUNKS_PER_THREAD))))


def check_chunks(chunks: object, names: Sequence[str], shape: Sequence[int],
                 n_threads: int) -> tuple[int, ...]:
    """``chunks`` as a chunk length per axis. None: automatic; an int: at most that many
    cells per chunk; a mapping from axis names to lengths (others whole) or a sequence of
    lengths in axis order. Lengths beyond an axis are clipped to it."""
    if chunks is None:
        return auto_chunks(shape, default_chunk_target(math.prod(shape), n_threads))
    if isinstance(chunks, Mapping):
        unknown = sorted(set(chunks) - set(names))
        if unknown:
            raise ValueError(f"chunks names {unknown}, which are not axes {list(names)}")
        lengths = [chunks.get(k, n) for k, n in zip(names, shape, strict=True)]
    elif isinstance(chunks, (list, tuple)):
        if len(chunks) != len(names):
            raise ValueError(f"chunks must have one length per axis {list(names)}, got "
                             f"{list(chunks)!r}")
        lengths = list(chunks)
    else:
        return auto_chunks(shape, check_int("chunks", chunks, 1))
    out = []
    for k, n, c in zip(names, shape, lengths, strict=True):
        out.append(min(n, check_int(f"chunks[{k!r}]", c, 1)))
    return tuple(out)


def make_spec(base: object, axes: object, settings: Any, chunks: object,
              n_threads: int) -> AtlasSpec:
    """Validate everything an atlas needs before any cell runs (``TypeError`` /
    ``ValueError`` naming the field and the value)."""
    base = _check_base(base)
    axes = _check_axes(axes, base)
    settings = settings_with(settings, {})
    check_periodicity_settings(settings.q_max, settings.m_max, settings.n_strobe)
    shape = tuple(a.size for a in axes.values())
    _check_cells(axes, base, settings)
    return AtlasSpec(base, axes, settings, check_chunks(chunks, list(axes), shape, n_threads))


# -- chunks ----------------------------------------------------------------------------
def chunk_slices(spec: AtlasSpec, index: Sequence[int]) -> tuple[slice, ...]:
    return tuple(slice(i * c, min(n, (i + 1) * c))
                 for i, c, n in zip(index, spec.chunks, spec.shape, strict=True))


def chunk_tasks(spec: AtlasSpec, indices: Sequence[tuple[int, ...]] | None = None
                ) -> list[ChunkTask]:
    """Tasks for the chunks ``indices`` (default: all), costliest first (so that a long
    chunk does not finish alone at the end while the other threads idle)."""
    if indices is None:
        indices = list(itertools.product(*(range(n) for n in spec.chunk_grid)))
    tasks = []
    for index in indices:
        sl = chunk_slices(spec, index)
        grids = {k: a[s] for (k, a), s in zip(spec.axes.items(), sl, strict=True)}
        tasks.append(ChunkTask(tuple(index), sl, spec.base, grids, spec.settings, 0.0))
    costs = _span_costs(spec, tasks)
    tasks = [replace(t, cost=c) for t, c in zip(tasks, costs, strict=True)]
    tasks.sort(key=lambda t: -t.cost)
    return tasks


def _span_costs(spec: AtlasSpec, tasks: list[ChunkTask]) -> list[float]:
    """Estimated cost of each chunk, without building rows: the sum over its cells of
    the radians the fastest tone turns through in the transient and windows (the kernels
    step at most half a radian of it; simulated time alone ranked the chunks backwards,
    small eta having long spans but few events per unit time), weighted by ``1 +
    log(1 + u0)``: stronger forcing means faster, stiffer slip and more events (on a
    Stribeck panel the chunks of largest u0 cost about 8 times those of the smallest)."""
    nu = spec.axes.get("nu", np.array([spec.base.nu]))
    spans = {}
    for fixed, p in _plan_groups(spec.axes, spec.base):
        plan = plan_cells(p, nu, spec.settings)
        span = plan.t_transient + plan.t_segment * plan.n_segment * np.maximum(plan.tries, 1)
        spans[tuple(fixed.values())] = span * p.eta * np.maximum(1.0, plan.nu_exact)
    costs = []
    names = [k for k in spec.base.plan_fields() if k in spec.axes]
    for t in tasks:
        n_other = math.prod(g.size for k, g in t.grids.items()
                            if k not in names + ["nu", "u0"])
        u0 = t.grids.get("u0", np.array([spec.base.u0]))
        weight = n_other * float(np.sum(1.0 + np.log1p(u0)))
        jn = t.slices[list(spec.axes).index("nu")] if "nu" in spec.axes else slice(None)
        total = 0.0
        for values in itertools.product(*(t.grids[k] for k in names)):
            total += float(spans[tuple(float(v) for v in values)][jn].sum())
        costs.append(total * weight)
    return costs


def compute_chunk(task: ChunkTask, n_threads: int | None = None,
                  stop_requested: Callable[[], bool] | None = None
                  ) -> tuple[tuple[int, ...], dict[str, np.ndarray]]:
    """Measure the cells of a chunk (those of ``task.todo``) by
    :func:`~fricenv.cells.measure_cells` and return the chunk's index and its variables,
    each shaped like the chunk; cells not run hold the fill values (status
    ``STATUS_NOT_RUN``). Runs on a worker or locally.

    Stopping (see :func:`fricenv.cells.run_cells`): ``stop_requested()`` becoming true
    returns the chunk with the cells finished so far; Ctrl-C raises
    :class:`~fricenv.calls.SweepInterrupted` whose ``results`` are that same pair.
    """
    shape = tuple(g.size for g in task.grids.values())
    mesh = np.meshgrid(*task.grids.values(), indexing="ij")
    values = {k: m.ravel() for k, m in zip(task.grids, mesh, strict=True)}
    todo = slice(None) if task.todo is None else np.flatnonzero(task.todo)
    stopped = None
    try:
        cells = measure_cells(task.base, {k: v[todo] for k, v in values.items()},
                              task.settings, n_threads, stop_requested)
    except SweepInterrupted as stop:
        stopped, cells = stop, stop.results
    measured = variables_from_stats(cells.stats, cells.period, cells.status, cells.labels,
                                    cells.lyapunov)
    if task.todo is None:
        variables = measured
    else:  # (a cell depends on its own values only: a subset runs as in the whole chunk)
        variables = empty_variables((math.prod(shape),))
        for k, v in measured.items():
            variables[k][todo] = v
    result = task.index, {k: v.reshape(shape) for k, v in variables.items()}
    if stopped is not None:
        stopped.results = result
        raise stopped
    return result


def variables_from_stats(stats: np.ndarray, period: np.ndarray, status: np.ndarray,
                         labels: np.ndarray, lyapunov: np.ndarray) -> dict[str, np.ndarray]:
    """The stored variables from window statistics (layout ``ST_*``), as ``RegimeMap``'s
    properties derive them, and the Lyapunov exponents (NaN where not measured)."""
    d = stats[..., ST_DURATION]
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(d > 0, stats[..., ST_STICK_TIME] / np.where(d > 0, d, 1), np.nan)
    out = {"stick_fraction": frac, "n_stick": stats[..., ST_N_STICK],
           "n_reversal": stats[..., ST_N_REVERSAL], "v_min": stats[..., ST_V_MIN],
           "v_max": stats[..., ST_V_MAX], "period": period, "status": status,
           "lyapunov": lyapunov, "label": labels}
    return {k: np.ascontiguousarray(out[k], dtype=VARIABLES[k][0]) for k in VARIABLES}


def empty_variables(shape: Sequence[int]) -> dict[str, np.ndarray]:
    return {k: np.full(tuple(shape), fill, dtype=dtype) for k, (dtype, fill) in VARIABLES.items()}


def run_local(tasks: Sequence[ChunkTask], n_threads: int | None = None
              ) -> Iterator[tuple[tuple[int, ...], dict[str, np.ndarray]]]:
    """Chunks one after the other on this machine's numba threads, yielded as they finish
    (the caller stores each before the next runs, so memory holds one chunk)."""
    for task in tasks:
        yield compute_chunk(task, n_threads)
