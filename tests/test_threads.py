"""Parallel kernels called from several Python threads, from Dask workers with two threads,
and before a fork: the results equal a serial run's and the process survives.

numba's ``workqueue`` layer aborts the whole process (SIGABRT) when two threads enter
parallel kernels at once, so every scenario runs in a fresh interpreter: a crash fails its
test instead of ending pytest. :mod:`fricenv.jit` loads TBB from the ``tbb`` wheel's own
path, and serialises parallel calls where the layer is not thread-safe; the scenarios run
on the layer this install gives and, forced by ``NUMBA_THREADING_LAYER``, on
``workqueue``.
"""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: A scenario's limit: generous, since a cold numba cache compiles for a minute or more.
TIMEOUT = 900
#: The layer this install gives, and the fallback forced.
LAYERS = [None, "workqueue"]


def _has_tbb_wheel() -> bool:
    try:
        importlib.metadata.distribution("tbb")
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


def _run(script: str, tmp_path: Path, layer: str | None = None) -> str:
    """Run ``script`` in a fresh interpreter on this checkout's fricenv, with numba's
    threading layer left to fricenv (``layer`` None) or forced; its stdout. Neither
    ``LD_LIBRARY_PATH`` nor ``NUMBA_THREADING_LAYER`` is inherited: the loader must find
    TBB without help."""
    path = tmp_path / "scenario.py"
    path.write_text(script)
    env = {k: v for k, v in os.environ.items()
           if k not in ("LD_LIBRARY_PATH", "NUMBA_THREADING_LAYER")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")
    if layer is not None:
        env["NUMBA_THREADING_LAYER"] = layer
    out = subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                         env=env, timeout=TIMEOUT, cwd=tmp_path)
    assert out.returncode == 0, (f"exit code {out.returncode}\n{out.stdout[-2000:]}\n"
                                 f"{out.stderr[-4000:]}")
    assert "already using GNU OpenMP" not in out.stderr, out.stderr[-4000:]
    return out.stdout


_TWO_THREADS = """
import threading
import numpy as np
import fricenv

def in_two_threads(run):
    out = [None, None]
    def work(i):
        out[i] = run()
    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out
"""

_REGIME_MAPS = _TWO_THREADS + """
U0 = np.geomspace(0.2, 100.0, 6)
NU = np.linspace(0.1, 3.0, 6)

def run():
    return fricenv.regime_map("coulomb", u0=U0, nu=NU, progress=False)

serial = run()
for m in in_two_threads(run):
    for name in ("labels", "stats", "status", "period"):
        assert np.array_equal(getattr(m, name), getattr(serial, name), equal_nan=True), name
print("same")
"""


@pytest.mark.parametrize("layer", LAYERS)
def test_regime_maps_in_two_threads_equal_a_serial_one(tmp_path, layer):
    assert "same" in _run(_REGIME_MAPS, tmp_path, layer)


_VECTOR_ENVS = _TWO_THREADS + """
from fricenv.envs.vector import PARALLEL_MIN_ENVS, StickSlipVectorEnv

N = max(64, PARALLEL_MIN_ENVS)

def run():
    env = StickSlipVectorEnv(num_envs=N, scene="self_excited", randomize=True,
                             max_episode_steps=40)
    assert env._step_kernel is env._steppers.step_batch_parallel
    rng = np.random.default_rng(7)
    seen = [env.reset(seed=3)[0]]
    for _ in range(150):
        a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, reward, term, trunc, _ = env.step(a)
        seen += [obs, reward, term, trunc]
    env.close()
    return seen

serial = run()
for seen in in_two_threads(run):
    assert len(seen) == len(serial)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(seen, serial))
print("same")
"""


@pytest.mark.parametrize("layer", LAYERS)
def test_vector_envs_stepped_in_two_threads_equal_a_serial_one(tmp_path, layer):
    assert "same" in _run(_VECTOR_ENVS, tmp_path, layer)


_DASK = """
import os
import numpy as np
import xarray as xr
from distributed import Client, LocalCluster
import fricenv

if __name__ == "__main__":
    axes = {"u0": np.geomspace(0.2, 40.0, 7), "nu": np.array([0.25, 0.5, 0.9, 1.3, 2.0]),
            "eta": np.array([0.2, 0.6, 1.667])}
    local = fricenv.atlas("coulomb", axes, chunks=6, progress=False)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        pids = client.run(os.getpid)
        dist = fricenv.atlas("coulomb", axes, client=client, chunks=6, progress=False)
        assert client.run(os.getpid) == pids  # no worker died (Dask retries a lost task)
        layers = client.run(lambda: fricenv.threading_info().layer)
    xr.testing.assert_identical(dist, local)
    print("same", *layers.values())
"""


def test_dask_worker_with_two_threads_equals_the_local_atlas(tmp_path):
    pytest.importorskip("distributed", reason="Dask is the scale extra")
    out = _run(_DASK, tmp_path)
    assert "same" in out
    if _has_tbb_wheel():
        assert out.split()[-1] == "tbb"


_FORK = _TWO_THREADS + """
import multiprocessing as mp
import numba
from fricenv import OscillatorParams

PLANT = OscillatorParams.preset("coulomb", eta=1.0)
PARAMS = [PLANT.replace(u0=u0, nu=0.5) for u0 in (0.5, 2.0)]
SHORT = dict(transient_min=20.0, window_min=20.0)

def labels(p):
    return fricenv.cell_statistics([p], **SHORT)[0].tolist()

if __name__ == "__main__":
    # parallel kernels in the parent, from two threads at once
    in_two_threads(lambda: fricenv.regime_map(PLANT, [0.5, 2.0], [0.5], progress=False,
                                              **SHORT))
    here = [labels(p) for p in PARAMS]
    with mp.get_context("fork").Pool(2) as pool:
        there = pool.map_async(labels, PARAMS, chunksize=1).get(timeout=300)
    assert there == here, (there, here)
    # a fork while another thread is inside a parallel section: the child starts unlocked
    from fricenv.jit import parallel_section
    entered, leave = threading.Event(), threading.Event()
    def hold():
        with parallel_section():
            entered.set()
            leave.wait()
    holder = threading.Thread(target=hold)
    holder.start()
    entered.wait()
    with mp.get_context("fork").Pool(1) as pool:
        there = pool.map_async(labels, PARAMS, chunksize=1).get(timeout=300)
    leave.set()
    holder.join()
    assert there == here, (there, here)
    print("same", numba.threading_layer())
"""


@pytest.mark.skipif(sys.platform == "win32", reason="no fork on Windows")
@pytest.mark.parametrize("layer", LAYERS)
def test_fork_pools_work_after_parallel_kernels_in_threads(tmp_path, layer):
    """Process pools started by fork after parallel kernels ran in the parent (numba's
    GNU OpenMP layer is not fork-safe: its forked workers hang or crash), on a fork-safe
    layer."""
    same, used = _run(_FORK, tmp_path, layer).split()[-2:]
    assert same == "same"
    assert used in ("tbb", "workqueue")


def test_the_layer_asked_for_is_fork_safe() -> None:
    """What fricenv asks numba for when ``fricenv.jit`` is imported."""
    import numba

    import fricenv.jit  # noqa: F401  (its import sets the layer)

    if os.environ.get("NUMBA_THREADING_LAYER"):
        pytest.skip("the user chose the threading layer")
    assert numba.config.THREADING_LAYER in ("safe", "forksafe")


_INFO = """
import os
import numba
import fricenv

info = fricenv.threading_info()
assert info.layer == numba.threading_layer(), info
assert info.user_layer == os.environ.get("NUMBA_THREADING_LAYER"), info
assert info.num_threads >= 1 and info.max_threads >= info.num_threads, info
print(info.layer, info.thread_safe, info.serialised, info.fork_safe, info.tbb_loaded,
      info.tbb_path)
"""


def test_threading_info_reports_a_thread_safe_layer_with_tbb(tmp_path):
    layer, thread_safe, serialised, fork_safe, tbb, path = _run(_INFO, tmp_path).split()
    assert (thread_safe, serialised, fork_safe) == ("True", "False", "True")
    if _has_tbb_wheel():  # (the wheel's libtbb, found without LD_LIBRARY_PATH)
        assert (layer, tbb) == ("tbb", "True")
        assert Path(path).is_file()


def test_threading_info_reports_a_user_layer_and_the_lock(tmp_path):
    layer, thread_safe, serialised, fork_safe, *_ = _run(_INFO, tmp_path, "workqueue").split()
    assert (layer, thread_safe, serialised, fork_safe) == ("workqueue", "False", "True",
                                                          "True")


_LOCK = """
import threading
import numpy as np
import fricenv
from fricenv.jit import parallel_section

P = [fricenv.OscillatorParams.preset("coulomb", u0=u0, nu=0.5) for u0 in (0.5, 2.0, 8.0)]
serial = fricenv.cell_statistics(P)
out = []
with parallel_section():  # a parallel kernel of another thread waits for this one
    worker = threading.Thread(target=lambda: out.append(fricenv.cell_statistics(P)))
    worker.start()
    worker.join(2.0)
    assert worker.is_alive() and not out
worker.join()
for a, b in zip(out[0], serial):
    assert np.array_equal(a, b, equal_nan=True)
print("serialised")
"""


def test_the_lock_serialises_parallel_calls_on_workqueue(tmp_path):
    assert "serialised" in _run(_LOCK, tmp_path, "workqueue")
