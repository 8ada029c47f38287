"""The atomic counter with which parallel kernels share their work out."""

import numpy as np
import pytest
from numba import njit, prange
from numba.core.errors import TypingError

from fricenv.atomic import fetch_add


@njit(parallel=True)
def _claim_all(n, n_workers, counter, hits):
    for _ in prange(n_workers):
        i = fetch_add(counter, 0, 1)
        while i < n:
            fetch_add(hits, i, 1)  # atomic too, so a doubly claimed index shows as 2
            i = fetch_add(counter, 0, 1)


@njit
def _add(arr, idx, inc):
    return fetch_add(arr, idx, inc)


def test_workers_claim_every_index_exactly_once():
    n, n_workers = 20_000, 4
    counter = np.zeros(1, dtype=np.int64)
    hits = np.zeros(n, dtype=np.int64)
    _claim_all(n, n_workers, counter, hits)
    assert np.all(hits == 1)
    assert counter[0] == n + n_workers  # each worker's last claim came back empty


def test_returns_the_old_value_and_adds():
    arr = np.array([3, 10], dtype=np.int64)
    assert _add(arr, 1, 5) == 10
    assert _add(arr, 1, -2) == 15
    assert arr.tolist() == [3, 13]


@pytest.mark.parametrize(
    "arr",
    [np.zeros(2), np.zeros((2, 2), dtype=np.int64), np.zeros(4, dtype=np.int64)[::2]],
    ids=["float", "2-d", "strided"],
)
def test_rejects_other_than_a_contiguous_1d_int64_array(arr):
    with pytest.raises(TypingError):
        _add(arr, 0, 1)
