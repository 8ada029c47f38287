"""Every result of the golden file, recomputed bit for bit.

The golden file (``tests/golden/golden.npz``, written by ``tests/golden/make_golden.py``)
holds trajectories of every method, stats-only runs, a small regime map of each friction
law and 200-step rollouts of each environment, single and vector. A refactor must leave
all of them identical to the last bit.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

_HERE = Path(__file__).with_name("golden")
_spec = importlib.util.spec_from_file_location("make_golden", _HERE / "make_golden.py")
make_golden = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_golden)


@pytest.fixture(scope="module")
def golden() -> dict[str, np.ndarray]:
    with np.load(make_golden.GOLDEN) as f:
        return dict(f)


@pytest.fixture(scope="module")
def now() -> dict[str, np.ndarray]:
    return make_golden.compute()


def test_same_entries(golden, now):
    assert sorted(golden) == sorted(now)


def test_bit_for_bit(golden, now):
    differ = []
    for key, ref in golden.items():
        got = now[key]
        if got.dtype != ref.dtype or got.shape != ref.shape:
            differ.append(f"{key}: {got.dtype}{got.shape} vs {ref.dtype}{ref.shape}")
        elif got.tobytes() != ref.tobytes():
            i = np.flatnonzero(got.ravel().view(np.uint8) != ref.ravel().view(np.uint8))
            differ.append(f"{key}: first differing byte {int(i[0])} of {ref.nbytes}")
    assert not differ, f"{len(differ)} of {len(golden)} entries differ:\n" + "\n".join(differ)
