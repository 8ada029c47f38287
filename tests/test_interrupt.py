"""Ctrl-C and SIGTERM stop every kind of sweep within about a second, keeping each cell
finished before the signal; a resumed run computes only the rest and equals an
uninterrupted one bit for bit.

Each sweep runs in a child process that warms its kernels, prints ``ready``, starts a
sweep of one chunk (so that the signal lands inside a chunk, where nothing was kept
before) and gets the signal a moment later.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import fricenv
from fricenv.calls import SweepInterrupted
from fricenv.cells import STATUS_NOT_RUN
from fricenv.maps import NOT_COMPUTED

ROOT = Path(__file__).resolve().parents[1]
#: Longest a signal may take to stop the sweep, its saving included (seconds, on a busy
#: machine; well under one on a quiet one).
STOP_S = 5.0
#: Time allowed the child, numba compilation from a cold cache included.
CHILD_TIMEOUT_S = 600.0
#: When the signal is sent after ``ready``, as a share of the time the same sweep took in
#: this process: cells have finished, the sweep has not, on a fast machine or a loaded one.
SIGNAL_AT = 0.35
N = 24
U0 = np.geomspace(0.5, 50.0, N)
NU = np.linspace(0.3, 2.7, N)
SETTINGS = fricenv.SweepSettings(window_min=4000.0)

_CHILD = """
import signal, sys, time
import numpy as np
import fricenv
from fricenv.calls import SweepInterrupted

# (a test run started in the background hands SIGINT down ignored: restore Ctrl-C)
signal.signal(signal.SIGINT, signal.default_int_handler)

kind, path = sys.argv[1], sys.argv[2]
settings = fricenv.SweepSettings(window_min=4000.0)
u0, nu = np.geomspace(0.5, 50.0, {n}), np.linspace(0.3, 2.7, {n})
fricenv.cell_statistics([fricenv.OscillatorParams.preset("stribeck")], settings)  # warm
if kind == "atlas":  # (its first call imports xarray, zarr and Dask)
    fricenv.atlas("stribeck", {{"u0": u0[:1]}}, settings=settings, progress=False)
print("ready", flush=True)
try:
    if kind == "map":
        fricenv.regime_map("stribeck", u0, nu, settings=settings, path=path,
                           chunk_size=u0.size * nu.size, progress=False)
    elif kind == "atlas":
        fricenv.atlas("stribeck", {{"u0": u0, "nu": nu}}, path=path, settings=settings,
                      chunks=u0.size * nu.size, progress=False)
    elif kind.startswith("dask"):
        from distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
        fricenv.atlas("stribeck", {{"u0": u0[:1], "nu": nu[:1]}}, client=client,
                      settings=settings, progress=False)  # the worker's kernels warm
        print("cluster", flush=True)
        fricenv.atlas("stribeck", {{"u0": u0, "nu": nu}}, path=path, settings=settings,
                      chunks=u0.size * nu.size // 8, client=client, progress=False)
    else:
        base = fricenv.OscillatorParams.preset("stribeck")
        cells = [base.replace(u0=float(a), nu=float(b)) for a in u0 for b in nu]
        try:
            fricenv.cell_statistics(cells, settings)
        except SweepInterrupted as stop:
            np.savez(path, *stop.results)
            raise
finally:
    print("stopped", time.perf_counter(), flush=True)
"""


@pytest.fixture(scope="module")
def full() -> fricenv.RegimeMap:
    """The sweep of every test here, run without a stop (timed, warm)."""
    fricenv.regime_map("stribeck", U0[:2], NU[:2], settings=SETTINGS, progress=False)
    start = time.perf_counter()
    rmap = fricenv.regime_map("stribeck", U0, NU, settings=SETTINGS, progress=False)
    rmap.meta["seconds"] = time.perf_counter() - start
    return rmap


def _interrupted_child(kind: str, path: Path, signum: int, full: fricenv.RegimeMap,
                       ignoring: bool = False) -> tuple[float, int, str]:
    """Run the sweep ``kind`` in a child, send it ``signum`` once it is sweeping; the
    seconds from the signal until the exception reached the child's own code (the sweep
    stopped and its cells saved), the child's return code and its stderr. ``ignoring``:
    the child starts with SIGINT ignored, as the children of a background job do. Kind
    ``dask-terminal`` sends the signal to the child's whole process group, its Dask
    workers too, as Ctrl-C in a terminal does."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if ignoring else None
    try:  # (an ignored signal stays ignored in a child, across exec)
        child = subprocess.Popen([sys.executable, "-c", _CHILD.format(n=N), kind, str(path)],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 env=env, cwd=ROOT,
                                 start_new_session=kind == "dask-terminal")
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    try:
        assert child.stdout is not None and child.stderr is not None
        line = child.stdout.readline().strip()
        assert line == "ready", child.stderr.read()
        if kind.startswith("dask"):
            line = child.stdout.readline().strip()
            assert line == "cluster", child.stderr.read()
        time.sleep(SIGNAL_AT * full.meta["seconds"])
        sent = time.perf_counter()
        if kind == "dask-terminal":
            os.killpg(child.pid, signum)
        else:
            child.send_signal(signum)
        child.wait(timeout=CHILD_TIMEOUT_S)
        out, err = child.stdout.read(), child.stderr.read()
    finally:
        child.kill()
    assert out.startswith("stopped "), err[-2000:]
    latency = float(out.split()[1]) - sent  # perf_counter is system-wide on Linux
    assert "KeyboardInterrupt" in err or "SweepInterrupted" in err, err[-2000:]
    print(f"\n[{kind}, {signal.Signals(signum).name}] stopped in {latency:.3f} s")
    return latency, child.returncode, err


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_stopped_regime_map_keeps_its_finished_cells(tmp_path, full, signum) -> None:
    path = tmp_path / "m.npz"
    latency, code, _ = _interrupted_child("map", path, signum, full)
    assert latency <= STOP_S and code != 0
    kept = fricenv.RegimeMap.load(path)
    assert 0 < kept.done.sum() < N * N, "the signal came before any cell or after all"
    assert np.all(kept.labels[~kept.done] == NOT_COMPUTED)
    for name in ("labels", "stats", "period", "status"):  # the kept cells as they are
        np.testing.assert_array_equal(getattr(kept, name)[kept.done],
                                      getattr(full, name)[kept.done])
    ran = []
    resumed = fricenv.regime_map("stribeck", U0, NU, settings=SETTINGS, path=path,
                                 progress=False, callback=lambda m, n: ran.append(n))
    assert sum(ran) == N * N - kept.done.sum()  # only the rest
    for name in ("labels", "stats", "period", "status", "done"):
        np.testing.assert_array_equal(getattr(resumed, name), getattr(full, name))


def test_a_sweep_started_with_ctrl_c_ignored_still_stops_on_it(tmp_path, full) -> None:
    """A shell starts a background job (``pytest &``, ``nohup``) with SIGINT ignored, and
    its children inherit that; the sweep child restores Python's Ctrl-C, so these tests
    and the stress script's signal probes judge the sweep, not how the run was started."""
    path = tmp_path / "m.npz"
    latency, code, _ = _interrupted_child("map", path, signal.SIGINT, full, ignoring=True)
    assert latency <= STOP_S and code != 0
    assert 0 < fricenv.RegimeMap.load(path).done.sum() < N * N


def test_stopped_cell_statistics_hand_back_their_finished_cells(tmp_path, full) -> None:
    path = tmp_path / "cells.npz"
    latency, _, _ = _interrupted_child("cells", path, signal.SIGINT, full)
    assert latency <= STOP_S
    with np.load(path) as f:
        labels, stats, period, status = (f[f"arr_{i}"] for i in range(4))
    done = status != STATUS_NOT_RUN
    assert 0 < done.sum() < N * N
    assert np.all(labels[~done] == NOT_COMPUTED) and np.all(np.isnan(stats[~done]))
    # (cell_statistics measures a cell as a map does: the map's cells, row by row)
    whole = (full.labels.ravel(), full.stats.reshape(N * N, -1), full.period.ravel(),
             full.status.ravel())
    for kept, cell in zip((labels, stats, period, status), whole, strict=True):
        np.testing.assert_array_equal(kept[done], cell[done])


def test_sweep_interrupted_is_a_keyboard_interrupt() -> None:
    stop = SweepInterrupted((1, 2), signal.SIGTERM)
    assert isinstance(stop, KeyboardInterrupt) and stop.results == (1, 2)
    assert "SIGTERM" in str(stop)


def test_stop_requested_returns_the_finished_cells_and_marks_the_rest() -> None:
    """``run_cells``' stop_requested: a stop asked for at once leaves every cell unrun,
    a request never made changes nothing."""
    from fricenv.cells import plan_cells, run_cells
    from fricenv.layout import METHOD_EVENT

    base = fricenv.OscillatorParams.preset("stribeck")
    plan = plan_cells(base, NU[:4], SETTINGS)
    P = np.repeat(base.to_array()[None], 4, axis=0)
    P[:, 9] = plan.nu_exact * P[:, 8]
    spans = (plan.t_transient, plan.t_segment, plan.n_segment, plan.tries)
    stats, status, period = run_cells(P, *spans, SETTINGS, METHOD_EVENT,
                                      stop_requested=lambda: False)
    assert np.all(status != STATUS_NOT_RUN)
    again = run_cells(P, *spans, SETTINGS, METHOD_EVENT)
    np.testing.assert_array_equal(again[0], stats)


@pytest.mark.parametrize("kind", ["atlas", "dask", "dask-terminal"])
def test_a_stopped_atlas_keeps_its_finished_cells(tmp_path, monkeypatch, full, kind) -> None:
    """Local and Dask atlases: the chunks running at the signal store what they finished
    (label stored), the rest of them stays not computed, and a resumed run computes the
    rest only and equals an uninterrupted atlas. On Dask, Ctrl-C to the client alone
    raised a plain KeyboardInterrupt, and Ctrl-C in a terminal (to the workers too) a
    bare TimeoutError after 10 s with the finished chunks dropped."""
    from fricenv.atlas import regime_map_dataset

    path = tmp_path / "a.zarr"
    latency, code, err = _interrupted_child(kind, path, signal.SIGINT, full)
    assert latency <= STOP_S and code != 0
    assert "fricenv.calls.SweepInterrupted: sweep stopped by SIGINT" in err, err[-2000:]
    assert "TimeoutError" not in err, err[-2000:]
    kept = fricenv.open_atlas(path).load()
    done = kept.label.values != NOT_COMPUTED
    assert 0 < done.sum() < N * N, "the signal came before any cell or after all"
    assert np.all(kept.status.values[~done] == STATUS_NOT_RUN)
    axes = {"u0": U0, "nu": NU}
    whole = regime_map_dataset(full)  # (an atlas equals the regime map, cell for cell)
    for name in whole.data_vars:
        np.testing.assert_array_equal(kept[name].values[done], whole[name].values[done])
    from fricenv.atlas import core

    ran = []
    real = core.compute_chunk

    def counting(task, *args):
        cells = np.prod([g.size for g in task.grids.values()])
        ran.append(int(cells if task.todo is None else task.todo.sum()))
        return real(task, *args)

    monkeypatch.setattr(core, "compute_chunk", counting)
    resumed = fricenv.atlas("stribeck", axes, path=path, settings=SETTINGS,
                            progress=False).load()
    assert sum(ran) == N * N - done.sum()  # only the rest
    for name in whole.data_vars:
        np.testing.assert_array_equal(resumed[name].values, whole[name].values)


def test_a_signal_never_returns_before_the_kernel_has() -> None:
    """``run_stoppable`` hands control back only once ``run()`` has returned, however the
    signal falls: on Python 3.11 an exception raised inside ``Thread.join`` marks a live
    thread as finished, and the caller then read cells the kernel was still writing."""
    from fricenv.calls import run_stoppable

    class Signalled(Exception):
        pass

    def handler(signum, frame):
        raise Signalled

    previous = signal.signal(signal.SIGUSR1, handler)
    main = threading.get_ident()
    try:
        for delay in (0.0, 0.01, 0.05, 0.1, 0.2):
            began, returned = _signalled_run(run_stoppable, Signalled, main, delay)
            assert returned or not began, f"returned while the kernel ran (signal at {delay} s)"
    finally:
        signal.signal(signal.SIGUSR1, previous)


def _signalled_run(run_stoppable, signalled: type[Exception], main: int, delay: float
                   ) -> tuple[bool, bool]:
    """``run_stoppable`` of a kernel that is still writing 0.2 s after its abort, with
    SIGUSR1 sent to the main thread ``delay`` seconds after the kernel begins (0: from
    before the call, so it may fall before the kernel has begun); whether the kernel
    began, and whether it had returned when the call did."""
    began, asked, returned = (threading.Event() for _ in range(3))
    timer = threading.Timer(delay, signal.pthread_kill, (main, signal.SIGUSR1))

    def run() -> None:
        began.set()
        if delay > 0.0:
            timer.start()
        asked.wait(10.0)
        time.sleep(0.2)
        returned.set()

    with pytest.raises(signalled):
        if delay == 0.0:
            timer.start()
        run_stoppable(run, asked.set)
        time.sleep(1.0)  # (not reached: the signal comes first)
    timer.join()
    return began.is_set(), returned.is_set()


def test_a_dask_stop_never_waits_for_chunks_no_worker_runs() -> None:
    """``distributed.wait`` raises on its timeout: a stop with chunks queued and no worker
    to run them (a cluster of none, or workers killed by the terminal's Ctrl-C) ended in a
    bare TimeoutError after 10 s, having cancelled nothing."""
    from distributed import Client, LocalCluster

    from fricenv.atlas import core
    from fricenv.atlas import distributed as D

    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        spec = core.make_spec("coulomb", {"u0": [1.0, 2.0, 3.0]}, None, 1, 1)
        run = D.DistributedRun(client, core.chunk_tasks(spec))
        for task in core.chunk_tasks(spec):
            run._submit(task)
        start = time.monotonic()
        kept = run.stop()
        assert time.monotonic() - start < 2.0
        assert kept == [] and not run.pending


def test_a_worker_process_under_a_nanny_ignores_the_terminals_ctrl_c():
    """Ctrl-C in a terminal reached a local cluster's worker processes and ended them with
    the chunks they held; their warm-up now shields those a nanny manages, not a worker
    that is its own program (no nanny) or a thread of another."""
    from distributed import Client, LocalCluster

    from fricenv.atlas.distributed import shield_from_terminal_ctrl_c

    before = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        assert not shield_from_terminal_ctrl_c(has_nanny=False)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        out: list[bool] = []
        t = threading.Thread(target=lambda: out.append(shield_from_terminal_ctrl_c(True)))
        t.start()
        t.join()
        assert out == [False] and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert shield_from_terminal_ctrl_c(has_nanny=True)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)

    def handler() -> str:  # (in the worker process)
        return str(signal.getsignal(signal.SIGINT))

    def shield(dask_worker) -> bool:  # (as WarmKernels.setup does, in the worker process)
        from fricenv.atlas.distributed import shield_from_terminal_ctrl_c

        return shield_from_terminal_ctrl_c(bool(getattr(dask_worker, "nanny", None)))

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        assert list(client.run(handler).values()) != [str(signal.SIG_IGN)]
        assert list(client.run(shield).values()) == [True]
        assert list(client.run(handler).values()) == [str(signal.SIG_IGN)]
