"""Aggregate scores of few training runs the way deep-RL evaluation recommends: the
interquartile mean (IQM) with a bootstrap confidence interval that resamples training runs
and, in blocks of plant seeds, episodes, and performance profiles with a bootstrap band
(Agarwal et al., "Deep reinforcement learning at the edge of the statistical precipice",
NeurIPS 2021). numpy only.

A benchmark cell is a matrix of scores: one row per training run (a controller without
training seeds has one row) and one column per evaluation episode, the columns grouped by
evaluation seed (``strata``). Every row faces the same episodes: the same plants, drawn
from the same seeds.

The bootstrap has two stages, applied together to every replicate:

1. resample the rows (training runs) with replacement: a training seed is a random draw of
   the training procedure, the source of variation the interval must cover for a learned
   controller;
2. within each evaluation seed's block, resample the columns (episodes) with replacement:
   plants are random draws too, and each evaluation seed keeps its number of episodes, as
   in the experiment.

This is not rliable's "stratified bootstrap", which resamples the runs of each task on
their own and knows no episodes: here training runs and episodes are resampled together,
the episodes in blocks of plant seeds (one block per evaluation seed), because every run
faces the same plants. :func:`score_matrix` gives a cell in the ``(runs x tasks)`` form
rliable reads, for anyone who wants its statistics instead.

The resampled columns are the same for every resampled row. Episodes are crossed with the
training runs, not nested in them (every model faces the same plants), so a plant that is
hard for one model is hard for all; resampling each row's episodes on its own would treat
those shared plants as independent and give too narrow an interval (Owen, "The pigeonhole
bootstrap", Ann. Appl. Stat. 2007). With one row only the second stage acts. Intervals
are percentile intervals of the replicates; every draw comes from one seeded
``numpy.random.Generator``, so a table is reproducible.

Comparisons of cells measured on the same episodes (a controller against zero
excitation, a condition against another) use :func:`paired_ci`: one set of indices per
replicate, applied to every cell involved, so the episode-to-episode variation they share
cancels in the ratio instead of widening its interval.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

N_BOOT = 2000  #: bootstrap replicates of every interval and band
CONFIDENCE = 0.95
#: The IQM drops this share of the values from each end (scipy.stats.trim_mean's rule:
#: ``int(0.25 n)`` values each side).
TRIM = 0.25

Strata = int | Sequence[int] | np.ndarray | None
#: The largest bootstrap an interval may allocate: its index arrays and replicates, in
#: bytes. ``n_boot=10**9`` on a benchmark cell asked for 37 GiB and died in numpy.
MAX_BOOT_BYTES = 2 * 1024**3


@dataclass(frozen=True)
class Interval:
    """A point estimate and its confidence interval ``[lo, hi]``."""

    estimate: float
    lo: float
    hi: float

    def format(self, digits: int = 2, scale: float = 1.0, suffix: str = "",
               signed: bool = False) -> str:
        """``estimate [lo, hi]`` for a table cell (each value times ``scale``; ``signed``:
        the estimate with its sign, e.g. a gap)."""
        if not np.isfinite(self.estimate):
            return "n/a"
        e = f"{scale * self.estimate:{'+' if signed else ''}.{digits}f}"
        lo, hi = (f"{scale * v:.{digits}f}" for v in (self.lo, self.hi))
        return f"{e}{suffix} [{lo}, {hi}]"


@dataclass(frozen=True)
class Profile:
    """A performance profile: the fraction of episodes with cost at most ``taus[i]``
    (``fraction``) and its pointwise bootstrap band ``[lo, hi]``."""

    taus: np.ndarray
    fraction: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


# -- the aggregate ----------------------------------------------------------------------------
def _no_nan(a: np.ndarray, name: str) -> None:
    """Refuse NaN, naming its first index: sorting puts NaN last, so the IQM would trim it
    as the best score and an interval would look finite around a failed measurement."""
    bad = np.argwhere(np.isnan(a))
    if bad.size:
        where = tuple(int(i) for i in bad[0])
        raise ValueError(f"{name} holds NaN ({bad.shape[0]} of {a.size} values), first at "
                         f"index {where[0] if len(where) == 1 else where}")


def _values(values: np.ndarray, axis: int | None, name: str = "values"
            ) -> tuple[np.ndarray, int]:
    """``values`` as floats free of NaN, raveled for ``axis=None``, and ``axis`` checked
    against their dimensions (an out-of-range axis was a bare ``IndexError``)."""
    a = np.asarray(values, dtype=float)
    _no_nan(a, name)
    if axis is None:
        return a.ravel(), 0
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)):
        raise ValueError(f"axis must be an integer or None, got {axis!r}")
    if not -a.ndim <= axis < a.ndim:
        raise ValueError(f"axis={axis} is out of range for {name} of shape {a.shape}")
    return a, int(axis) % a.ndim


def iqm(values: np.ndarray, axis: int | None = None) -> np.ndarray | float:
    """Interquartile mean: the mean of the values left after dropping ``int(n / 4)`` from
    each end (``axis=None``: all values; else along ``axis``).

    Robust to a few failed runs or episodes, unlike the mean, and uses half the data,
    unlike the median, so its interval is narrower for few runs. NaN is refused
    (``ValueError`` naming its index): no order puts a missing score where it belongs.
    """
    a, axis = _values(values, axis)
    n = a.shape[axis]
    if n == 0:
        raise ValueError("iqm needs at least one value, got an empty array")
    k = int(TRIM * n)
    kept = np.take(np.sort(a, axis=axis), np.arange(k, n - k), axis=axis)
    out = kept.mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def mean(values: np.ndarray, axis: int | None = None) -> np.ndarray | float:
    """The plain mean, with :func:`iqm`'s signature and checks (for statistics that want
    totals, such as the share of stuck time a controller removes)."""
    a, axis = _values(values, axis)
    if a.shape[axis] == 0:
        raise ValueError("mean needs at least one value, got an empty array")
    out = a.mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


# -- resampling -------------------------------------------------------------------------------
def _matrix(scores: np.ndarray, name: str = "scores") -> np.ndarray:
    a = np.asarray(scores, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"{name} must be a non-empty (runs x episodes) matrix, got shape "
                         f"{np.shape(scores)}")
    _no_nan(a, name)
    return a


def stratum_labels(strata: Strata, n_cols: int) -> np.ndarray:
    """One label per column: ``None`` one stratum, an int ``S`` that many equal blocks of
    consecutive columns (evaluation seeds in the benchmark's order), or the labels."""
    if strata is None:
        return np.zeros(n_cols, dtype=np.int64)
    if isinstance(strata, (int, np.integer)) and not isinstance(strata, bool):
        s = int(strata)
        if s < 1 or n_cols % s:
            raise ValueError(f"strata={s} must be >= 1 and divide the {n_cols} episodes")
        return np.repeat(np.arange(s), n_cols // s)
    labels = np.asarray(strata)
    if labels.shape != (n_cols,):
        raise ValueError(f"strata must hold one label per episode ({n_cols}), got shape "
                         f"{labels.shape}")
    if labels.dtype.kind == "f":
        # NaN is unequal to itself: its columns joined no stratum and kept the
        # uninitialised indices of np.empty.
        _no_nan(labels, "strata")
    return labels


def _check_boot(n_boot: int, confidence: float, per_replicate: int = 1,
                shape: tuple[int, int] = (1, 1)) -> None:
    """Refuse a bootstrap that cannot mean anything or cannot fit in memory:
    ``per_replicate`` is how many float64 values one replicate holds at once (indices,
    resampled cells, their sorted copies), ``shape`` the cell's ``(runs, episodes)``
    for the message."""
    if isinstance(n_boot, bool) or not isinstance(n_boot, (int, np.integer)) or n_boot < 1:
        raise ValueError(f"n_boot must be an integer >= 1, got {n_boot!r}")
    if (isinstance(confidence, bool) or not isinstance(confidence, (int, float, np.number))
            or not 0.0 < confidence < 1.0):
        raise ValueError(f"confidence must be a number in (0, 1), got {confidence!r}")
    runs, episodes = shape
    need = 8 * int(n_boot) * int(per_replicate)
    if need > MAX_BOOT_BYTES:
        raise ValueError(f"n_boot={n_boot} on a {runs} x {episodes} cell needs "
                         f"{need / 1024**3:.1f} GiB, over the {MAX_BOOT_BYTES / 1024**3:.0f} "
                         f"GiB limit (MAX_BOOT_BYTES); use fewer replicates")


def bootstrap_indices(n_rows: int, strata: Strata, n_cols: int, n_boot: int,
                      rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Row indices ``(n_boot, n_rows)`` and column indices ``(n_boot, n_cols)`` of the
    two-stage bootstrap (training runs, then episodes within each block of plant seeds;
    see the module's docstring). Column ``j`` of a
    replicate comes from the stratum of original column ``j``, so each stratum keeps its
    size and place."""
    labels = stratum_labels(strata, n_cols)
    rows = rng.integers(0, n_rows, size=(n_boot, n_rows))
    cols = np.empty((n_boot, n_cols), dtype=np.int64)
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        cols[:, members] = members[rng.integers(0, members.size, size=(n_boot, members.size))]
    return rows, cols


def _counts(idx: np.ndarray, n: int) -> np.ndarray:
    """How often each of ``n`` originals was drawn in each replicate (a row of ``idx``)."""
    out = np.zeros((idx.shape[0], n))
    np.add.at(out, (np.arange(idx.shape[0])[:, None], idx), 1.0)
    return out


def _take(cell: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The replicates of ``cell``, ``(n_boot, rows, cols)``; a one-row cell keeps its row."""
    r = rows if cell.shape[0] > 1 else np.zeros_like(rows[:, :1])
    return cell[r[:, :, None], cols[:, None, :]]


def _percentiles(replicates: np.ndarray, confidence: float) -> tuple[np.ndarray, np.ndarray]:
    alpha = 100.0 * (1.0 - confidence) / 2.0
    lo, hi = np.nanpercentile(replicates, [alpha, 100.0 - alpha], axis=0)
    return lo, hi


# -- intervals --------------------------------------------------------------------------------
Aggregate = Callable[..., "np.ndarray | float"]


def iqm_ci(scores: np.ndarray, strata: Strata = None, n_boot: int = N_BOOT,
           confidence: float = CONFIDENCE, seed: int = 0,
           aggregate: Aggregate = iqm) -> Interval:
    """``aggregate`` (the IQM) of all of a cell's scores with its bootstrap interval
    (training runs, then episodes within each evaluation seed's block of plant seeds).
    ``scores``: a ``(runs, episodes)`` matrix (a 1-D array is one run);
    ``strata``: the episodes' evaluation seeds (see :func:`stratum_labels`)."""
    cell = _matrix(scores)
    _check_boot(n_boot, confidence, sum(cell.shape) + 2 * cell.size, cell.shape)
    rows, cols = bootstrap_indices(cell.shape[0], strata, cell.shape[1], n_boot,
                                   np.random.default_rng(seed))
    reps = np.asarray(aggregate(_take(cell, rows, cols).reshape(n_boot, -1), axis=1))
    lo, hi = _percentiles(reps, confidence)
    return Interval(float(aggregate(cell)), float(lo), float(hi))


def paired_ci(statistic: Callable[..., np.ndarray | float], cells: Sequence[np.ndarray],
              strata: Strata = None, n_boot: int = N_BOOT, confidence: float = CONFIDENCE,
              seed: int = 0) -> Interval:
    """``statistic(*cells)`` of cells measured on the same episodes, with a bootstrap
    interval drawing the same indices for every cell.

    Each cell is a ``(runs, episodes)`` matrix with the same episodes (columns). Cells with
    several rows must have the same number (the same training runs, e.g. one policy in two
    conditions) and share the row indices; a one-row cell (a controller without training
    seeds) keeps its row. ``statistic`` receives the cells as arrays ``(..., runs,
    episodes)`` and reduces the last two axes (the original cells first, then all
    replicates at once, with a leading replicate axis), e.g.
    ``lambda c, z: 1 - stat(c) / stat(z)`` with ``stat = x.mean(axis=(-2, -1))``.
    """
    mats = [_matrix(c, f"cells[{i}]") for i, c in enumerate(cells)]
    if not mats:
        raise ValueError("paired_ci needs at least one cell")
    _check_boot(n_boot, confidence, sum(mats[0].shape) + 2 * sum(m.size for m in mats),
                mats[0].shape)
    n_cols = mats[0].shape[1]
    if any(m.shape[1] != n_cols for m in mats):
        raise ValueError(f"the cells must share their episodes, got {[m.shape for m in mats]}")
    n_rows = {m.shape[0] for m in mats} - {1}
    if len(n_rows) > 1:
        raise ValueError(f"cells with several runs must have the same number, got "
                         f"{[m.shape[0] for m in mats]}")
    rows, cols = bootstrap_indices(max(n_rows, default=1), strata, n_cols, n_boot,
                                   np.random.default_rng(seed))
    with np.errstate(divide="ignore", invalid="ignore"):
        point = float(np.asarray(statistic(*mats)))
        reps = np.asarray(statistic(*(_take(m, rows, cols) for m in mats)), dtype=float)
    if reps.shape != (n_boot,):
        raise ValueError(f"statistic must reduce each replicate to one number, got shape "
                         f"{reps.shape} for {n_boot} replicates")
    if not np.isfinite(reps).any():
        return Interval(point, float("nan"), float("nan"))
    lo, hi = _percentiles(reps, confidence)
    return Interval(point, float(lo), float(hi))


def cell_stat(aggregate: Aggregate = iqm) -> Callable[[np.ndarray], np.ndarray]:
    """``aggregate`` over the last two axes (runs, episodes) of a cell or its replicates,
    the form :func:`paired_ci`'s statistics reduce with."""
    def stat(cell: np.ndarray) -> np.ndarray:
        a = np.asarray(cell, dtype=float)
        return np.asarray(aggregate(a.reshape(*a.shape[:-2], -1), axis=-1))

    return stat


# -- performance profiles ---------------------------------------------------------------------
def tau_grid(costs: Sequence[np.ndarray], n: int = 100) -> np.ndarray:
    """``n`` log-spaced thresholds spanning all the given costs (from half the smallest
    positive one to twice the largest), so the profiles of every controller of a scene
    share one axis."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise ValueError(f"n must be an integer >= 2, got {n!r}")
    arrays = [np.asarray(c, dtype=float).ravel() for c in costs]
    if not arrays:
        raise ValueError("tau_grid needs the costs of at least one cell, got none")
    flat = np.concatenate(arrays)
    pos = flat[np.isfinite(flat) & (flat > 0)]
    if pos.size == 0:
        return np.geomspace(1e-3, 1.0, n)
    lo, hi = 0.5 * pos.min(), 2.0 * pos.max()
    return np.geomspace(lo, max(hi, 2.0 * lo), n)


def performance_profile(costs: np.ndarray, taus: np.ndarray, strata: Strata = None,
                        n_boot: int = N_BOOT, confidence: float = CONFIDENCE,
                        seed: int = 0) -> Profile:
    """Fraction of all of a cell's episodes (every run) with cost at most each of ``taus``,
    and its pointwise bootstrap band (the two-stage scheme of :func:`iqm_ci`).

    A replicate weights original episode ``(i, j)`` by how often row ``i`` and column ``j``
    were drawn, so the band is one matrix product, not a sort per replicate.
    """
    cell = _matrix(costs, "costs")
    taus = np.asarray(taus, dtype=float)
    r, c = cell.shape
    _check_boot(n_boot, confidence, 2 * (r + c) + (r + 1) * taus.size, (r, c))
    if taus.ndim != 1 or taus.size < 1 or np.isnan(taus).any() or np.any(np.diff(taus) < 0):
        raise ValueError(f"taus must be a non-empty increasing 1-D array, got {taus!r}")
    below = (cell[:, :, None] <= taus).astype(float)  # (runs, episodes, taus)
    rows, cols = bootstrap_indices(r, strata, c, n_boot, np.random.default_rng(seed))
    per_row = np.einsum("bj,ijt->bit", _counts(cols, c), below)  # (n_boot, runs, taus)
    reps = np.einsum("bi,bit->bt", _counts(rows, r), per_row) / (r * c)
    lo, hi = _percentiles(reps, confidence)
    return Profile(taus, below.mean(axis=(0, 1)), lo, hi)


# -- tails, wins and rliable's form -----------------------------------------------------------
def cvar(values: np.ndarray, share: float = 0.05, axis: int | None = None
         ) -> np.ndarray | float:
    """The mean of the worst ``share`` of the values (the lowest: returns, where higher is
    better), at least one value: the conditional value at risk of the left tail.

    The IQM drops the tails by design; a controller that fails badly on one plant in
    twenty is then indistinguishable from one that never does, so a table that ranks by
    IQM shows this beside it. ``ceil(share * n)`` values are averaged (``axis=None``: all
    values; else along ``axis``).
    """
    if (isinstance(share, bool) or not isinstance(share, (int, float, np.number))
            or not 0.0 < share <= 1.0):
        raise ValueError(f"share must be a number in (0, 1], got {share!r}")
    a, axis = _values(values, axis)
    n = a.shape[axis]
    if n == 0:
        raise ValueError("cvar needs at least one value, got an empty array")
    k = max(1, int(np.ceil(share * n - 1e-9)))
    out = np.take(np.sort(a, axis=axis), np.arange(k), axis=axis).mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def win_share(cell: np.ndarray, ref: np.ndarray) -> np.ndarray | float:
    """The share of paired episodes in which ``cell`` scores above ``ref`` (ties count
    half): each row (training run) of ``cell`` against the reference's episode on the same
    plant. ``ref`` has one row (a controller without training seeds) or as many as
    ``cell``. Reduces the last two axes, so it also takes :func:`paired_ci`'s replicates.
    """
    c, r = np.asarray(cell, dtype=float), np.asarray(ref, dtype=float)
    if c.ndim < 2 or r.ndim < 2 or c.shape[-1] != r.shape[-1]:
        raise ValueError(f"cell and ref must be (runs, episodes) matrices with the same "
                         f"episodes, got shapes {c.shape} and {r.shape}")
    if r.shape[-2] not in (1, c.shape[-2]):
        raise ValueError(f"ref must have one row or as many as cell ({c.shape[-2]}), got "
                         f"{r.shape[-2]}")
    wins = (c > r).astype(float) + 0.5 * (c == r)
    return np.asarray(wins.mean(axis=(-2, -1)))


def score_matrix(cells: Sequence[np.ndarray]) -> np.ndarray:
    """Cells of one controller on several tasks (scenes), each ``(runs, episodes)`` on the
    same episodes, as the ``(runs x tasks)`` matrix rliable reads: row ``i * episodes + j``
    holds training run ``i``'s score on episode ``j`` of every task.

    rliable's aggregates (``rliable.metrics.aggregate_iqm``: ``scipy.stats.trim_mean(x,
    0.25)`` over the flattened matrix) then pool a task's column exactly as :func:`iqm`
    pools the cell. Its interval differs: rliable resamples each task's rows on its own,
    while :func:`iqm_ci` resamples training runs and plant blocks together.
    """
    mats = [_matrix(c, f"cells[{t}]") for t, c in enumerate(cells)]
    if not mats:
        raise ValueError("score_matrix needs the cell of at least one task, got none")
    if any(m.shape != mats[0].shape for m in mats):
        raise ValueError(f"every task's cell must have the same (runs, episodes) shape, got "
                         f"{[m.shape for m in mats]}")
    return np.stack([m.ravel() for m in mats], axis=1)
