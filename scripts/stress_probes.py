"""The stress matrix's later classes: their calls (run by the worker, with
``stress_entries.py`` as its plugin) and the probes that need a process of their own
(threads, signals, a second writer), each judged from its exit and its files only.

A child process prints ``RESULT <json>`` (``{"kind", "wrong", "error"}``) when it has a
judgment of its own; an exit by a signal or code 134 (abort) is a *crash*, no exit within
the bound a *hang*.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from callcheck import Outcome  # noqa: E402

#: Seconds a sweep gets to exit after SIGINT / SIGTERM (the Ctrl-C bound).
SIGNAL_BOUND_S = 2.0
#: Seconds of computing before the signal: cells have finished by then.
SIGNAL_AFTER_S = 2.0
#: Transient and window of the signalled sweeps' cells: three times the default, so that a
#: 100 x 100 Stribeck sweep in one chunk runs about 10 s on two cores, far past the signal.
_LONG = "S = fricenv.SweepSettings(transient_min=300.0, window_min=300.0)\n"
#: The small atlas that the damage class copies and damages.
ATLAS_SPEC = {"base": "coulomb", "axes": {"u0": (0.5, 3.0, 8), "nu": (0.2, 2.0, 15)},
              "chunks": (4, 5)}

_HEAD = textwrap.dedent("""
    import json, signal, sys, threading, time
    import numpy as np
    import fricenv
    # (a stress run started in the background hands SIGINT down ignored: restore Ctrl-C)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    def result(wrong=(), kind="returned", error=""):
        print("RESULT " + json.dumps({"kind": kind, "wrong": list(wrong), "error": error}),
              flush=True)
    def judged(e):
        names = {c.__name__ for c in type(e).__mro__}
        return "clear" if names & {"TypeError", "ValueError", "RuntimeError"} else "bare"
    def in_threads(job, n=2):
        out, errors = [None] * n, []
        def run(i):
            try:
                out[i] = job()
            except Exception as e:
                errors.append(e)
        ts = [threading.Thread(target=run, args=(i,)) for i in range(n)]
        for t in ts:
            t.start()
        for t in ts:
            t.join()
        if errors:
            e = errors[0]
            result(kind=judged(e), error=f"{type(e).__name__}: {str(e)[:300]}")
            sys.exit(0)
        return out
    def same(a, b):
        if isinstance(a, (list, tuple)):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
""")

_THREADS = {
    "regime_map": """
        def job():
            m = fricenv.regime_map("coulomb", u0=np.geomspace(0.2, 100, 30),
                                   nu=np.linspace(0.1, 3, 30), progress=False)
            return [m.labels, m.stats, m.period, m.status]
    """,
    "cell_statistics": """
        cells = [fricenv.OscillatorParams(u0=a, nu=b, b1=0.2, b3=0.16)
                 for a in np.geomspace(0.2, 20, 12) for b in np.linspace(0.1, 3, 12)]
        def job():
            return list(fricenv.cell_statistics(cells))
    """,
    "vector_env": """
        import gymnasium as gym
        def job():
            venv = gym.make_vec("fricenv/StickSlip-v0", num_envs=64,
                                vectorization_mode="vector_entry_point")
            obs = [venv.reset(seed=0)[0]]
            rng = np.random.default_rng(0)
            for _ in range(30):
                a = rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)
                obs.append(venv.step(a)[0])
            venv.close()
            return obs
    """,
}
_THREADS_TAIL = """
    serial = job()
    for _ in range(3):
        if not all(same(o, serial) for o in in_threads(job)):
            result(["two threads' results differ from a serial run's"])
            sys.exit(0)
    result()
"""
_FORK = """
    import multiprocessing as mp
    def job(_=None):
        m = fricenv.regime_map("coulomb", u0=np.geomspace(0.2, 100, 30),
                               nu=np.linspace(0.1, 3, 30), progress=False)
        return m.labels
    serial = job()
    with mp.get_context("fork").Pool(2) as pool:
        out = pool.map_async(job, range(2)).get(timeout=float(sys.argv[1]))
    result([] if all(same(o, serial) for o in out) else ["fork pool's maps differ"])
"""


def _env(pythonpath: str | None) -> dict:
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    return env


def _judge_exit(rc: int | None, out: str, err: str, seconds: float) -> Outcome:
    if rc is None:
        return Outcome("hang", seconds)
    if rc < 0 or rc == 134:
        said = [x for x in err.splitlines() if "terminating" in x.lower() or "Fatal" in x]
        return Outcome("crash", seconds, error=f"exit code {rc}: "
                       + " ".join((said or err.strip().splitlines())[-1:])[:300])
    for line in out.splitlines():
        if line.startswith("RESULT "):
            r = json.loads(line[7:])
            return Outcome(r["kind"], seconds, wrong=r["wrong"], error=r["error"])
    last = (err.strip().splitlines() or [f"exit code {rc}, no result"])[-1]
    return Outcome("bare", seconds, error=last[:300])


def run_child(body: str, args: list[str], pythonpath: str | None, timeout: float) -> Outcome:
    """Run ``_HEAD + body`` in a fresh interpreter and judge its exit."""
    code = _HEAD + textwrap.dedent(body)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:  # (cwd: "-c" puts it first on the path)
        proc = subprocess.Popen([sys.executable, "-c", code, *args], env=_env(pythonpath),
                                cwd=tmp, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True, start_new_session=True)
        try:
            out, err = proc.communicate(timeout=timeout)
            rc: int | None = proc.returncode
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
            rc = None
    return _judge_exit(rc, out, err, time.monotonic() - t0)


def threads_class(pythonpath: str | None, budget: float) -> list[tuple[str, dict, Outcome]]:
    """Parallel kernels in two threads of one process (sound: no crash and the serial
    run's results), and a fork pool after a parallel kernel ran."""
    results = []
    for name, body in _THREADS.items():
        out = run_child(textwrap.dedent(body) + textwrap.dedent(_THREADS_TAIL), [],
                        pythonpath, budget * 6)
        results.append(("threads", {"job": name}, out))
    out = run_child(_FORK, [str(budget * 3)], pythonpath, budget * 6)
    results.append(("threads", {"job": "fork pool after a parallel kernel"}, out))
    return results


# -- signals ----------------------------------------------------------------------------------
_GRID = "U0, NU = np.linspace(0.5, 3, 100), np.linspace(0.2, 2, 100)\n"
_SWEEPS = {
    "regime_map": """
        fricenv.regime_map("stribeck", U0, NU, chunk_size=int(sys.argv[2]), path=sys.argv[1],
                           settings=S, progress=False,
                           callback=lambda m, n: print("cells", int(m.done.sum()), flush=True))
    """,
    "atlas": """
        fricenv.atlas("stribeck", {"u0": U0, "nu": NU}, path=sys.argv[1], chunks=(100, 100),
                      settings=S, progress=False)
    """,
    "cell_statistics": """
        cells = [fricenv.OscillatorParams(u0=a, nu=b, b1=0.2, b3=0.16)
                 for a in U0[::10] for b in NU]  # (1000 cells: 0.3 s to plan, then ~10 s)
        fricenv.cell_statistics(cells, fricenv.SweepSettings(transient_min=3000.0,
                                                             window_min=3000.0))
    """,
}
_WARM = """
    fricenv.regime_map("stribeck", [1.0], [0.5], progress=False)
    if sys.argv[3] == "atlas":  # (imports Dask, Zarr and xarray)
        fricenv.atlas("stribeck", {"u0": [1.0], "nu": [0.5]}, progress=False)
    print("go", flush=True)
"""


def _kept(kind: str, path: Path) -> int:
    """Cells the sweep's file holds as done (0 without a file, or with one that does not
    open: a file that loses every cell keeps none)."""
    try:
        return _done_cells(kind, path)
    except Exception:  # noqa: BLE001
        return 0


def _done_cells(kind: str, path: Path) -> int:
    import fricenv

    if kind == "regime_map":
        return int(fricenv.RegimeMap.load(path).done.sum()) if path.exists() else 0
    if kind == "atlas":
        if not path.exists():
            return 0
        return int(np.sum(np.asarray(fricenv.open_atlas(path)["label"].values) >= 0))
    return 0


def _read_lines(stream: object, lines: list) -> None:
    for line in stream:
        lines.append((time.monotonic(), line.strip()))


def signal_probe(kind: str, sig: int, chunk: int, pythonpath: str | None) -> Outcome:
    """A sweep that gets ``sig`` ``SIGNAL_AFTER_S`` seconds in. Hang: no exit within
    ``SIGNAL_BOUND_S`` (its latency is recorded); wrong: an exit that kept none of the
    cells finished before the signal (the sweep had computed for ``SIGNAL_AFTER_S``, or
    its callback had reported done cells); sound: a prompt exit keeping them."""
    code = _HEAD + _GRID + _LONG + textwrap.dedent(_WARM) + textwrap.dedent(_SWEEPS[kind]) + \
        "print('finished', flush=True)\n"
    lines: list = []
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / ("m.npz" if kind == "regime_map" else "a.zarr")
        proc = subprocess.Popen([sys.executable, "-c", code, str(path), str(chunk), kind],
                                env=_env(pythonpath), cwd=tmp, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True, start_new_session=True)
        reader = threading.Thread(target=_read_lines, args=(proc.stdout, lines), daemon=True)
        reader.start()
        deadline = time.monotonic() + 600.0  # (imports, and numba's cache, first)
        while not lines and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        if not lines:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            return Outcome("bare", time.monotonic() - t_start,
                           error=f"the sweep did not start (exit code {proc.returncode})")
        time.sleep(SIGNAL_AFTER_S)
        reported = max([int(t.split()[1]) for _, t in lines if t.startswith("cells ")],
                       default=0)
        finished = any(t == "finished" for _, t in lines)
        t0 = time.monotonic()
        proc.send_signal(sig)
        try:
            proc.wait(timeout=SIGNAL_BOUND_S)
            latency: float | None = time.monotonic() - t0
        except subprocess.TimeoutExpired:
            latency = None
            try:
                proc.wait(timeout=30.0)
                late = f"exited {time.monotonic() - t0:.1f} s after the signal"
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                late = "no exit within 30 s of the signal (killed)"
        reader.join(timeout=5.0)
        kept = _kept(kind, path)
    seconds = time.monotonic() - t0
    name = signal.Signals(sig).name
    if finished:
        return Outcome("returned", seconds, error=f"finished before the {name}: not judged")
    if latency is None:
        return Outcome("hang", seconds, error=f"{name}: {late}; kept {kept} cells")
    note = f"{name}: exit {proc.returncode} after {latency:.2f} s, kept {kept} cells"
    if kind != "cell_statistics" and kept == 0 or kept < reported:
        return Outcome("returned", seconds, wrong=[f"{note}, {reported} reported done"],
                       error=note)
    return Outcome("returned", seconds, error=note)


def signal_class(pythonpath: str | None) -> list[tuple[str, dict, Outcome]]:
    cases = [("regime_map", signal.SIGINT, 10000), ("atlas", signal.SIGINT, 0),
             ("cell_statistics", signal.SIGINT, 0), ("regime_map", signal.SIGTERM, 500)]
    return [("signal", {"sweep": kind, "signal": signal.Signals(sig).name, "chunk": chunk},
             signal_probe(kind, sig, chunk, pythonpath)) for kind, sig, chunk in cases]


# -- atlas stores -----------------------------------------------------------------------------
def damage_calls(store: Path, rng: np.random.Generator, flips: int) -> list[tuple[str, dict]]:
    """Damages of a copy of ``store``: ``flips`` single-bit flips in a chunk of each
    variable, a deleted ``stick_fraction`` chunk, a flip in the u0 coordinate, and a
    truncated, an invalid and a reshaped ``zarr.json``; each opened and resumed."""
    damages = []
    for var in ("label", "stick_fraction", "n_stick", "n_reversal", "v_min", "v_max",
                "period", "status"):
        chunk = store / var / "c" / "1" / "2"
        size = chunk.stat().st_size
        for off in rng.integers(0, size, flips):
            damages.append({"kind": "flip", "file": f"{var}/c/1/2", "offset": int(off),
                            "bit": int(rng.integers(8))})
    damages += [{"kind": "delete", "file": "stick_fraction/c/0/1"},
                {"kind": "flip", "file": "u0/c/0",
                 "offset": int(rng.integers((store / "u0/c/0").stat().st_size)), "bit": 3},
                {"kind": "truncate", "file": "stick_fraction/zarr.json"},
                {"kind": "garbage", "file": "zarr.json"},
                {"kind": "shape", "file": "label/zarr.json"}]
    return [("atlas_damage", {"good": str(store), "spec": ATLAS_SPEC, "damage": d,
                              "action": a}) for d in damages for a in ("open", "resume")]


def build_atlas(folder: Path) -> Path:
    import fricenv

    store = folder / "good.zarr"
    fricenv.atlas(ATLAS_SPEC["base"], {k: np.linspace(*v) for k, v in
                                       ATLAS_SPEC["axes"].items()},
                  path=store, chunks=ATLAS_SPEC["chunks"], progress=False)
    return store


_ATLAS_WRITER = """
    fricenv.atlas("stribeck", {"u0": np.linspace(0.5, 3, 150), "nu": np.linspace(0.2, 2, 150)},
                  path=sys.argv[1], chunks=(10, 10), progress=False)
"""


def atlas_writers(pythonpath: str | None, budget: float) -> Outcome:
    """A second ``atlas`` on a store while a first one writes it (same arguments): sound if
    one of them is refused with an error, wrong if both exit 0."""
    code = _HEAD + textwrap.dedent(_ATLAS_WRITER)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "a.zarr"
        args = [sys.executable, "-c", code, str(store)]
        first = subprocess.Popen(args, env=_env(pythonpath), cwd=tmp,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 600.0
        while not (store / "zarr.json").exists() and first.poll() is None \
                and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)
        running = first.poll() is None
        try:
            second = subprocess.run(args, env=_env(pythonpath), cwd=tmp, capture_output=True,
                                    text=True, timeout=budget * 12)
            rc2, err2 = second.returncode, second.stderr
        except subprocess.TimeoutExpired:
            rc2, err2 = None, ""
        try:
            first.communicate(timeout=budget * 12)
        except subprocess.TimeoutExpired:
            first.kill()
            first.communicate()
    seconds = time.monotonic() - t0
    if not running:
        return Outcome("returned", seconds, error="the first writer ended before the second "
                       "started: not judged")
    if rc2 is None:
        return Outcome("hang", seconds, error="the second writer did not end")
    if first.returncode == 0 and rc2 == 0:
        return Outcome("returned", seconds, wrong=["both writers of one atlas exited 0"])
    err = (err2.strip().splitlines() or [""])[-1]
    return Outcome("clear" if "Error" in err and str(store) in err else "bare", seconds,
                   error=err[:300])


# -- the other classes' calls --------------------------------------------------------------
HUGE = [
    ("atlas_huge", {"axes": {"u0": (0.1, 10, 10**4), "nu": (0.1, 3, 10**4),
                             "eta": (0.2, 2, 10**4)}}),
    ("atlas_huge", {"axes": {"u0": (0.1, 10, 10**4), "nu": (0.1, 3, 10**4),
                             "eta": (0.2, 2, 10**4)}, "path": True}),
    ("atlas_huge", {"axes": {"u0": (0.1, 10, 10**7), "nu": (0.1, 3, 10**7)}}),
    ("atlas_huge", {"axes": {"u0": (0.1, 10, 10**7), "nu": (0.1, 3, 10**7)}, "path": True}),
    ("atlas_huge", {"axes": {"u0": (0.1, 10, 10**3), "nu": (0.1, 3, 10**3),
                             "eta": (0.2, 2, 10**3), "lam": (0.1, 1, 10**3)}}),
]
_GARBAGE = (-1e300, 1e100, float("nan"))
_STATE_CHANGES = [{"mode": 0.0, "v": 5.0}, {"v": 1e300}, {"v": -1e300}, {"x": 1e13},
                  {"xfs": 1e300}, {"t": 1e17},
                  *({"work": g} for g in _GARBAGE),
                  *({"work_slot": (k / 8, g)} for k in range(8) for g in _GARBAGE)]
SET_STATE = [("set_state", {"env_id": e, "change": c})
             for e in ("fricenv/StickSlip-v0", "fricenv/StickSlipStribeck-v0")
             for c in _STATE_CHANGES]
POINTS = [("output_points", {"t_span": 1.2e5, "dt_out": 0.01}),
          ("output_points", {"t_span": 1e6, "dt_out": 0.01}),
          ("output_points", {"t_span": 10.0, "dt_out": 0.1, "t0": 1e15})]
TAMPERED = [("tampered_map", {"change": c, "action": a})
            for c in ("stats_inf", "stats_nan", "period", "status", "label")
            for a in ("load", "resume")]
UNCLEAR = [("unclear", {"case": c}) for c in ("from_array_short", "from_array_nan_mode",
                                             "state_nan_mode", "load_npy", "render_mode")]
