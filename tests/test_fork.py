"""Process pools started by fork work after a parallel kernel has run in the parent.

Numba's GNU OpenMP threading layer is not fork-safe: a forked worker of a process that has
run a parallel kernel on it hangs or crashes. :mod:`fricenv.jit` picks a fork-safe layer;
this runs the scenario in a fresh process, with a deadline instead of a hang.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest

import fricenv

_SCRIPT = """
import multiprocessing as mp
import numba
import numpy as np
import fricenv
from fricenv import OscillatorParams

PLANT = OscillatorParams.preset("coulomb", eta=1.0)
PARAMS = [PLANT.replace(u0=u0, nu=0.5) for u0 in (0.5, 2.0)]
SHORT = dict(transient_min=20.0, window_min=20.0)


def labels(p):
    return fricenv.cell_statistics([p], **SHORT)[0].tolist()


if __name__ == "__main__":
    # a parallel kernel in the parent: a small map, threads on
    fricenv.regime_map(PLANT, [0.5, 2.0], [0.5], progress=False, **SHORT)
    here = [labels(p) for p in PARAMS]
    with mp.get_context("fork").Pool(2) as pool:
        there = pool.map(labels, PARAMS, chunksize=1)
    assert there == here, (there, here)
    print("layer", numba.threading_layer())
"""


@pytest.mark.skipif(sys.platform == "win32", reason="no fork on Windows")
def test_fork_pool_after_a_parallel_kernel(tmp_path: Path) -> None:
    script = tmp_path / "fork_after_sweep.py"
    script.write_text(_SCRIPT)
    root = str(Path(fricenv.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    env.pop("NUMBA_THREADING_LAYER", None)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "already using GNU OpenMP" not in out.stderr
    layer = out.stdout.split()[-1]
    assert layer in ("tbb", "workqueue")


def test_the_layer_asked_for_is_fork_safe() -> None:
    if os.environ.get("NUMBA_THREADING_LAYER"):
        pytest.skip("the user chose the threading layer")
    assert numba.config.THREADING_LAYER in ("safe", "forksafe")
