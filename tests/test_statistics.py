"""The benchmark's statistics: interquartile mean, bootstrap intervals over runs and blocks
of plant seeds and performance profiles, against slow loop-by-loop references and by their
properties."""

from __future__ import annotations

import time

import numpy as np
import pytest
from fricenv_agents import statistics as S
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_subnormal=False)


def _iqm_slow(values) -> float:
    """The textbook rule, one value at a time: drop int(n / 4) from each end, average."""
    v = sorted(float(x) for x in np.ravel(values))
    k = len(v) // 4
    kept = v[k:len(v) - k]
    return sum(kept) / len(kept)


def _replicates_slow(cell: np.ndarray, strata: int, n_boot: int, seed: int,
                     stat=_iqm_slow) -> list[float]:
    """The two-stage bootstrap written out: draw the rows, then each evaluation seed's
    episodes, build the resampled matrix element by element and aggregate it."""
    r, c = cell.shape
    rows, cols = S.bootstrap_indices(r, strata, c, n_boot, np.random.default_rng(seed))
    out = []
    for b in range(n_boot):
        picked = [cell[rows[b, i] if r > 1 else 0, cols[b, j]]
                  for i in range(r) for j in range(c)]
        out.append(stat(picked))
    return out


def test_iqm_known_values_and_the_reference():
    assert S.iqm(np.arange(1, 9)) == 4.5  # mean of 3, 4, 5, 6
    assert S.iqm([7.0]) == 7.0 and S.iqm([1.0, 3.0]) == 2.0
    assert S.iqm([0, 0, 0, 100, 1, 1, 1, 1]) == 0.75  # 0, 1, 1, 1: the 100 is cut
    x = np.random.default_rng(0).normal(size=(4, 7))
    assert S.iqm(x) == pytest.approx(_iqm_slow(x))
    np.testing.assert_allclose(S.iqm(x, axis=1), [_iqm_slow(row) for row in x])
    scipy_stats = pytest.importorskip("scipy.stats")
    assert S.iqm(x) == pytest.approx(scipy_stats.trim_mean(x, 0.25, axis=None))
    with pytest.raises(ValueError, match="empty"):
        S.iqm([])


@settings(max_examples=60, deadline=None)
@given(arrays(float, st.integers(1, 40), elements=finite), st.randoms(use_true_random=False))
def test_iqm_of_a_constant_and_under_permutation(x, rnd):
    assert S.iqm(np.full(x.size, 3.25)) == 3.25
    perm = x.copy()
    rnd.shuffle(perm)
    assert S.iqm(perm) == pytest.approx(S.iqm(x), abs=1e-9)
    assert S.iqm(x) == pytest.approx(_iqm_slow(x), abs=1e-9)
    assert x.min() - 1e-9 <= S.iqm(x) <= x.max() + 1e-9  # (the mean's last bit)


def test_interval_matches_the_slow_reference():
    rng = np.random.default_rng(1)
    cell = rng.gamma(2.0, size=(3, 12))
    got = S.iqm_ci(cell, strata=4, n_boot=300, seed=5)
    reps = _replicates_slow(cell, 4, 300, 5)
    lo, hi = np.percentile(reps, [2.5, 97.5])
    assert got.estimate == pytest.approx(_iqm_slow(cell))
    assert (got.lo, got.hi) == pytest.approx((lo, hi))
    # a paired ratio through the same indices
    zero = rng.gamma(5.0, size=(1, 12))
    mean = S.cell_stat(S.mean)
    cut = S.paired_ci(lambda c, z: 1 - mean(c) / mean(z), [cell, zero], strata=4,
                      n_boot=300, seed=5)
    rows, cols = S.bootstrap_indices(3, 4, 12, 300, np.random.default_rng(5))
    ref = [1 - cell[rows[b][:, None], cols[b]].mean() / zero[0, cols[b]].mean()
           for b in range(300)]
    assert cut.estimate == pytest.approx(1 - cell.mean() / zero.mean())
    assert (cut.lo, cut.hi) == pytest.approx(tuple(np.percentile(ref, [2.5, 97.5])))


def test_two_stages_and_their_strata():
    rows, cols = S.bootstrap_indices(5, 4, 20, 200, np.random.default_rng(0))
    assert rows.shape == (200, 5) and rows.min() >= 0 and rows.max() == 4
    # each column stays in its evaluation seed's block of 5
    assert np.array_equal(cols // 5, np.broadcast_to(np.arange(20) // 5, (200, 20)))
    labels = [0, 1, 0, 1, 1, 0]
    _, cols = S.bootstrap_indices(1, labels, 6, 100, np.random.default_rng(1))
    assert np.array_equal(np.asarray(labels)[cols], np.broadcast_to(labels, (100, 6)))
    # one row: only the episodes vary; constant rows: only the training seeds do
    assert S.iqm_ci(np.arange(10.0)[None], n_boot=200).hi > S.iqm_ci(np.arange(10.0)[None],
                                                                     n_boot=200).lo
    by_run = np.repeat(np.arange(6.0)[:, None], 8, axis=1)
    iv = S.iqm_ci(by_run, strata=2, n_boot=500)
    assert iv.lo < iv.estimate < iv.hi  # rows differ: the first stage gives the width
    one = S.iqm_ci(by_run[:1], strata=2, n_boot=50)  # one row of equal episodes: none
    assert one.lo == one.estimate == one.hi == 0.0
    for bad in ({"strata": 3}, {"strata": [0, 1]}, {"n_boot": 0}, {"confidence": 1.0}):
        with pytest.raises(ValueError):
            S.iqm_ci(by_run, **bad)
    with pytest.raises(ValueError, match="same number"):
        S.paired_ci(lambda a, b: a.sum() - b.sum(), [by_run, by_run[:3]])
    with pytest.raises(ValueError, match="share their episodes"):
        S.paired_ci(lambda a, b: a.sum() - b.sum(), [by_run, by_run[:, :3]])


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 4), st.integers(1, 3), st.integers(1, 6), st.integers(0, 2**16))
def test_interval_contains_the_iqm_and_is_reproducible(runs, n_strata, per, seed):
    cell = np.random.default_rng(seed).lognormal(size=(runs, n_strata * per))
    iv = S.iqm_ci(cell, strata=n_strata, n_boot=400, seed=seed)
    tol = 1e-12 * cell.max()  # (the percentiles' interpolation rounds in the last bit)
    assert iv.lo - tol <= iv.estimate <= iv.hi + tol
    assert S.iqm_ci(cell, strata=n_strata, n_boot=400, seed=seed) == iv
    assert cell.min() - tol <= iv.lo and iv.hi <= cell.max() + tol


@settings(max_examples=40, deadline=None)
@given(arrays(float, st.tuples(st.integers(1, 3), st.integers(1, 12)),
              elements=st.floats(0, 1e3, allow_nan=False, allow_subnormal=False)),
       st.integers(0, 1000))
def test_profile_band_is_monotone_and_holds_the_profile(costs, seed):
    taus = S.tau_grid([costs], n=25)
    prof = S.performance_profile(costs, taus, n_boot=200, seed=seed)
    for curve in (prof.fraction, prof.lo, prof.hi):
        assert np.all(np.diff(curve) >= -1e-12) and curve.min() >= 0 and curve.max() <= 1
    assert np.all(prof.lo <= prof.fraction + 1e-12) and np.all(prof.fraction <= prof.hi + 1e-12)
    assert prof.fraction[-1] == 1.0  # every cost is at most the grid's end


def test_profile_matches_the_slow_reference():
    rng = np.random.default_rng(3)
    costs = rng.lognormal(size=(2, 9))
    taus = S.tau_grid([costs], n=7)
    prof = S.performance_profile(costs, taus, strata=3, n_boot=150, seed=2)
    assert np.allclose(prof.fraction, [(costs <= t).mean() for t in taus])
    rows, cols = S.bootstrap_indices(2, 3, 9, 150, np.random.default_rng(2))
    reps = np.array([[np.mean([costs[i, j] <= t for i in rows[b] for j in cols[b]])
                      for t in taus] for b in range(150)])
    assert np.allclose(prof.lo, np.percentile(reps, 2.5, axis=0))
    assert np.allclose(prof.hi, np.percentile(reps, 97.5, axis=0))


def test_a_benchmark_cell_takes_well_under_a_second():
    cell = np.random.default_rng(0).normal(size=(5, 100))
    S.iqm_ci(cell, strata=10)  # (first call: numpy's own warm-up)
    t = time.perf_counter()
    S.iqm_ci(cell, strata=10, n_boot=2000)
    S.performance_profile(np.exp(cell), S.tau_grid([np.exp(cell)]), strata=10)
    assert time.perf_counter() - t < 1.0


def test_interval_format():
    assert S.Interval(0.5, 0.25, 0.75).format(1, 100, " %") == "50.0 % [25.0, 75.0]"
    assert S.Interval(-1.234, -2.0, -1.0).format() == "-1.23 [-2.00, -1.00]"
    assert S.Interval(0.05, -0.01, 0.1).format(1, 100, " %", signed=True) == "+5.0 % [-1.0, 10.0]"
    assert S.Interval(float("nan"), 0, 1).format() == "n/a"


def test_nan_scores_are_refused_naming_the_index():
    with pytest.raises(ValueError, match=r"NaN .*index 3"):
        S.iqm([1.0, 2.0, 3.0, np.nan])
    with pytest.raises(ValueError, match=r"NaN .*index 2"):
        S.mean([1.0, 2.0, np.nan])
    cell = np.arange(12.0).reshape(2, 6)
    cell[1, 4] = np.nan
    with pytest.raises(ValueError, match=r"scores holds NaN .*\(1, 4\)"):
        S.iqm_ci(cell, strata=2, n_boot=50)
    with pytest.raises(ValueError, match=r"cells\[1\] holds NaN"):
        S.paired_ci(lambda a, b: a.mean(axis=(-2, -1)) - b.mean(axis=(-2, -1)),
                    [np.ones((2, 6)), cell], n_boot=50)
    with pytest.raises(ValueError, match=r"costs holds NaN"):
        S.performance_profile(cell, np.linspace(0, 12, 5), n_boot=50)


def test_nan_strata_labels_are_refused_not_read_as_garbage():
    labels = np.array([0.0, 0.0, 1.0, np.nan, 1.0, 1.0])
    for _ in range(3):  # the unchecked bootstrap answered differently call to call
        with pytest.raises(ValueError, match=r"strata holds NaN .*index 3"):
            S.iqm_ci(np.arange(6.0), strata=labels, n_boot=50, seed=1)


def test_bad_arguments_get_named_errors():
    x = np.arange(8.0).reshape(2, 4)
    for axis in (2, -3, "1", 1.0):
        with pytest.raises(ValueError, match=r"axis"):
            S.iqm(x, axis=axis)
    np.testing.assert_allclose(S.iqm(x, axis=-1), S.iqm(x, axis=1))
    for conf in ("0.9", 1.0, 0.0, None, True):
        with pytest.raises(ValueError, match=r"confidence must be a number in \(0, 1\)"):
            S.iqm_ci(x, confidence=conf, n_boot=10)
    with pytest.raises(ValueError, match=r"n_boot=1000000000 on a 2 x 4 cell needs .* GiB"):
        S.iqm_ci(x, n_boot=10**9)
    with pytest.raises(ValueError, match=r"n_boot=1000000000"):
        S.paired_ci(lambda a: a.mean(axis=(-2, -1)), [x], n_boot=10**9)
    with pytest.raises(ValueError, match=r"n_boot=1000000000"):
        S.performance_profile(x, np.linspace(0, 8, 4), n_boot=10**9)
    with pytest.raises(ValueError, match=r"at least one cell, got none"):
        S.tau_grid([])
    with pytest.raises(ValueError, match=r"n must be an integer >= 2, got 2.5"):
        S.tau_grid([x], n=2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"taus must be"):
        S.performance_profile(x, np.array([1.0, np.nan]), n_boot=10)


# -- tails, wins and rliable's form -----------------------------------------------------------
def test_cvar_is_the_mean_of_the_worst_share_and_at_least_one_value() -> None:
    v = np.arange(40.0)  # the worst 5 % of 40: the two lowest
    assert S.cvar(v, 0.05) == pytest.approx(0.5)
    assert S.cvar(np.array([3.0, -7.0, 1.0]), 0.05) == -7.0  # (one value at least)
    assert S.cvar(v, 1.0) == pytest.approx(v.mean())
    assert S.cvar(v, 0.05) <= S.iqm(v)
    with pytest.raises(ValueError, match="share"):
        S.cvar(v, 0.0)
    with pytest.raises(ValueError, match="NaN"):
        S.cvar(np.array([1.0, np.nan]))


def test_win_share_pairs_each_run_with_the_reference_on_the_same_plant() -> None:
    ref = np.array([[0.0, 1.0, 2.0, 3.0]])
    cell = np.array([[1.0, 0.0, 2.0, 4.0],   # wins 2, tie 1, loses 1
                     [9.0, 9.0, 9.0, 9.0]])  # wins 4
    assert S.win_share(cell, ref) == pytest.approx((2.5 + 4.0) / 8.0)
    assert S.win_share(ref, ref) == pytest.approx(0.5)
    # paired_ci hands it every replicate at once and gets one share each
    iv = S.paired_ci(S.win_share, [cell, ref], strata=2, n_boot=200)
    assert 0.0 <= iv.lo <= iv.estimate <= iv.hi <= 1.0
    with pytest.raises(ValueError, match="same episodes"):
        S.win_share(cell, ref[:, :3])


def test_score_matrix_pools_each_task_as_the_iqm_pools_its_cell() -> None:
    """rliable's IQM (``rliable.metrics.aggregate_iqm``) is scipy.stats.trim_mean(x, 0.25)
    over the flattened matrix: on one task's column it must equal the cell's IQM. Checked
    against rliable itself where it is installed (the ``dev`` extra), and against its
    documented definition always."""
    from scipy.stats import trim_mean

    rng = np.random.default_rng(3)
    cells = [rng.normal(t, 1 + t, size=(5, 50)) for t in range(3)]
    m = S.score_matrix(cells)
    assert m.shape == (250, 3)
    assert m[1 * 50 + 7, 2] == cells[2][1, 7]  # row: run i, episode j
    for t, cell in enumerate(cells):
        assert trim_mean(m[:, t], 0.25) == pytest.approx(S.iqm(cell), rel=1e-12)
    assert trim_mean(m, 0.25, axis=None) == pytest.approx(S.iqm(np.concatenate(cells)))
    try:
        from rliable import metrics
    except ImportError:
        return
    for t, cell in enumerate(cells):
        assert metrics.aggregate_iqm(m[:, [t]]) == pytest.approx(S.iqm(cell), rel=1e-12)
    assert metrics.aggregate_iqm(m) == pytest.approx(S.iqm(m), rel=1e-12)


def test_score_matrix_refuses_tasks_of_different_shapes() -> None:
    with pytest.raises(ValueError, match="same"):
        S.score_matrix([np.zeros((5, 50)), np.zeros((5, 40))])
    with pytest.raises(ValueError, match="at least one"):
        S.score_matrix([])
