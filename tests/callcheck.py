"""Run public calls of fricenv in a worker process with a time budget, and judge the answers.

Shared by the property suite (``tests/test_properties.py``) and ``scripts/stress.py``. A
call is plain data, ``(entry, kwargs)`` with an entry of :data:`ENTRIES`; the worker (this
file run as a script, importing whichever ``fricenv`` its ``PYTHONPATH`` finds) builds the
objects, makes the call and checks what comes back; the parent waits at most ``budget``
seconds for the answer. A call over budget gets SIGINT, which counts as honoured if the
worker answers within ``SIGINT_GRACE_S``; then the worker is killed and restarted.

Outcomes (``Outcome.kind``):

* ``"returned"``: an answer, with ``wrong`` listing what is wrong with it (empty: fine):
  a statistic inf or NaN while the status says OK, motion beyond the bound below
  presented as a result, a stick time above the duration, a block stuck all window long
  labelled as stick-slip;
* ``"clear"``: a documented exception (``TypeError``, ``ValueError``, ``RuntimeError``
  and its subclasses ``SimulationError``, ``MapInUseError``, ``ResetNeeded``; an
  ``OSError`` only where the call names a path that cannot be opened);
* ``"bare"``: any other exception (``EOFError``, ``MemoryError``, ``BadZipFile``...);
* ``"hang"``: no answer within the budget; ``"crash"``: the worker died.

The judge does not import ``fricenv.divergence``, so that it can judge code without it:
its bound on the motion is the same formula, written out again (:func:`motion_bound`).
"""

from __future__ import annotations

import math
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Seconds a worker gets to answer SIGINT before it is killed (the Ctrl-C bound).
SIGINT_GRACE_S = 1.0
#: The factor of the motion bound (fricenv.divergence.DIVERGENCE_FACTOR).
BOUND_FACTOR = 1e8
#: Exceptions a public call may raise for bad input or a run that cannot go on.
DOCUMENTED = ("TypeError", "ValueError", "RuntimeError", "SimulationError", "MapInUseError",
              "ResetNeeded")
_HEADER = struct.Struct("<Q")
_ENV_IDS = ("fricenv/StickSlip-v0", "fricenv/StickSlipSelfExcited-v0")
#: Calls a worker makes when it starts (see :class:`Worker`): one of each kernel's kinds.
WARM_UP = [
    ("run_stats", {"params": {}, "t_span": 10.0}),
    ("run_stats", {"params": {"b1": 0.2, "b3": 0.16}, "t_span": 10.0}),
    ("simulate", {"params": {"u0": 1.0}, "t_end": 10.0}),
    ("simulate", {"params": {"u0": 1.0, "b1": 0.2}, "t_end": 10.0}),
    ("simulate", {"params": {"u0": 1.0}, "t_end": 10.0, "method": "rk4"}),
    ("cell_statistics", {"params": [{"u0": 1.0}]}),
    ("cell_statistics", {"params": [{"u0": 1.0, "b1": 0.2}]}),
    ("regime_map", {"params": {}, "u0": [1.0], "nu": [0.5], "save": True}),
    *(("env", {"env_id": e, "make": {}, "options": None, "actions": [[0.0] * k],
               "sample": s}) for e, k in zip(_ENV_IDS, (1, 2), strict=True) for s in (None, 8)),
    *(("vector", {"env_id": e, "num_envs": n, "make": {}, "options": None, "steps": 2})
      for e in _ENV_IDS for n in (3, 70)),
]


@dataclass
class Outcome:
    kind: str  # returned, clear, bare, hang, crash
    seconds: float
    wrong: list[str] = field(default_factory=list)
    error: str = ""  # "TypeName: message" of an exception
    sigint_s: float | None = None  # hang: seconds until SIGINT was answered (None: never)

    @property
    def ok(self) -> bool:
        """Returned a sound answer or raised a documented exception."""
        return (self.kind == "returned" and not self.wrong) or self.kind == "clear"


# -- the parent side ----------------------------------------------------------------------
class Worker:
    """A worker process that makes calls one at a time (restarted after a hang or crash).

    ``warm_up``: calls made, without a time budget, whenever a worker starts: numba loads
    (or compiles) each kernel on its first call in a process, which is no part of any
    call's own cost. ``plugins``: files whose ``ENTRIES`` the worker adds to its own (see
    :func:`load_plugins`).
    """

    def __init__(self, pythonpath: str | None = None,
                 warm_up: list[tuple[str, dict]] = (), plugins: list[Path] = ()) -> None:
        self.pythonpath = pythonpath
        self.warm_up = list(warm_up)
        self.plugins = [str(Path(p).resolve()) for p in plugins]
        self.proc: subprocess.Popen | None = None

    def _start(self) -> None:
        env = dict(os.environ)
        if self.pythonpath is not None:
            env["PYTHONPATH"] = self.pythonpath
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()),
                                      *self.plugins],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, env=env)
        reply = self._read(600.0)  # imports (and loads numba's cache) first
        if reply != "ready":
            raise RuntimeError(f"the worker did not start: {reply!r}")
        for entry, kwargs in self.warm_up:
            self._send(entry, kwargs)
            if self._read(600.0) is None:
                raise RuntimeError(f"the worker's warm-up call {entry} {kwargs} did not end")

    def _send(self, entry: str, kwargs: dict) -> None:
        data = pickle.dumps((entry, kwargs))
        self.proc.stdin.write(_HEADER.pack(len(data)) + data)
        self.proc.stdin.flush()

    def _read(self, timeout: float) -> Any:
        """The next reply, or None if none came within ``timeout`` (or the worker died)."""
        out = self.proc.stdout
        deadline = time.monotonic() + timeout
        buf = b""
        need = _HEADER.size
        size = None
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([out], [], [], left)[0]:
                return None
            chunk = os.read(out.fileno(), need - len(buf))
            if not chunk:
                return None
            buf += chunk
            if len(buf) < need:
                continue
            if size is None:
                size = _HEADER.unpack(buf)[0]
                buf, need = b"", size
                continue
            return pickle.loads(buf)

    def call(self, entry: str, kwargs: dict, budget: float) -> Outcome:
        if self.proc is None or self.proc.poll() is not None:
            self._start()
        t0 = time.monotonic()
        try:
            self._send(entry, kwargs)
        except BrokenPipeError:
            self.close()
            return Outcome("crash", 0.0, error="the worker died before the call")
        reply = self._read(budget)
        seconds = time.monotonic() - t0
        if reply is not None:
            return Outcome(**reply)
        if self.proc.poll() is not None:
            self.close()
            return Outcome("crash", seconds, error=f"worker exit code {self.proc.returncode}")
        t1 = time.monotonic()
        self.proc.send_signal(signal.SIGINT)
        answer = self._read(SIGINT_GRACE_S)
        if answer is None:  # Ctrl-C not honoured: only a kill stops the call
            self.close()
            return Outcome("hang", seconds)
        return Outcome("hang", seconds, sigint_s=time.monotonic() - t1)

    def close(self) -> None:
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait()
            for f in (self.proc.stdin, self.proc.stdout):
                try:
                    f.close()
                except OSError:
                    pass
            self.proc = None


# -- the judge (also used by the worker) --------------------------------------------------
def motion_bound(p: Any, x0: float, v0: float, span: float) -> float:
    """``BOUND_FACTOR`` x the motion scale of fricenv.divergence x max(1, span), at most
    1e100: no plant whose slip damps large speeds comes near it."""
    u = p.amp1 + p.amp2
    band = (p.b1 - p.lam) / p.b3 if p.b3 > 0 and p.b1 > p.lam else 0.0
    scale = max(1.0, abs(x0), abs(v0), u, p.xfs, abs(p.V), p.lam * abs(p.V), abs(p.b1 * p.V),
                abs(p.b3) * abs(p.V) ** 3, math.sqrt(band) if band < math.inf else math.inf)
    return min(BOUND_FACTOR * scale * max(1.0, span), 1e100)


def judge_stats(s: Any, p: Any, x0: float, v0: float, span: float) -> list[str]:
    """What is wrong with a RunStats returned (so with status OK) by a run over ``span``."""
    wrong = []
    values = {k: getattr(s, k) for k in ("duration", "stick_time", "v_max", "v_min", "x_max",
                                         "x_min", "vr2_integral")}
    values.update(x_end=s.state.x, v_end=s.state.v)
    bad = [k for k, v in values.items() if not math.isfinite(v)]
    if bad:
        wrong.append(f"non-finite {bad} with status OK")
    if s.stick_time > s.duration:
        wrong.append(f"stick time {s.stick_time!r} above duration {s.duration!r}")
    size = max(abs(values[k]) for k in ("v_max", "v_min", "x_max", "x_min", "x_end", "v_end"))
    if math.isfinite(size) and size > motion_bound(p, x0, v0, span):
        wrong.append(f"|x| or |v| {size:.3g} beyond the motion bound, status OK")
    return wrong


def judge_cells(labels: Any, stats: Any, status: Any, params: list, x0: float, v0: float,
                spans: list[float]) -> list[str]:
    """What is wrong with sweep cells (rows of stats, layout fricenv.layout.ST_*)."""
    import numpy as np

    from fricenv.regimes import Regime

    stuck = getattr(Regime, "STUCK", None)
    wrong = []
    for i, p in enumerate(params):
        if status[i] != 0:
            continue
        row = np.asarray(stats[i], dtype=float)
        measured = np.delete(row, 9)  # (the maps skip the (v - V)^2 integral: NaN)
        if not np.all(np.isfinite(measured)):
            wrong.append(f"cell {i}: non-finite statistic with status OK")
        if row[1] > row[0]:
            wrong.append(f"cell {i}: stick time {row[1]!r} above duration {row[0]!r}")
        size = np.max(np.abs(row[5:9]))
        if np.isfinite(size) and size > motion_bound(p, x0, v0, spans[i]):
            wrong.append(f"cell {i}: |x| or |v| {size:.3g} beyond the motion bound, label "
                         f"{Regime(int(labels[i])).name}, status OK")
        if row[2] == row[3] == row[4] == 0 and row[1] > 0 and labels[i] != stuck:
            wrong.append(f"cell {i}: stuck all window long, labelled "
                         f"{Regime(int(labels[i])).name}")
    return wrong


# -- the worker side: one function per entry ----------------------------------------------
def _params(d: dict) -> Any:
    import fricenv

    return fricenv.OscillatorParams(**d)


def _simulate(params: dict, t_end: float, x0: float = 0.0, v0: float = 0.0,
              method: str = "auto", dt_out: float = 0.5) -> list[str]:
    import numpy as np

    import fricenv

    p = _params(params)
    tr = fricenv.simulate(p, t_end, x0=x0, v0=v0, method=method, dt_out=dt_out)
    wrong = judge_stats(tr.stats, p, x0, v0, t_end)
    if not (np.all(np.isfinite(tr.x)) and np.all(np.isfinite(tr.v))):
        wrong.append("non-finite trajectory with status OK")
    return wrong


def _run_stats(params: dict, t_span: float, x0: float = 0.0, v0: float = 0.0,
               method: str = "auto") -> list[str]:
    import fricenv

    p = _params(params)
    state = fricenv.OscillatorState.start(p, x0, v0)
    return judge_stats(fricenv.run_stats(p, t_span, state=state, method=method), p, x0, v0,
                       t_span)


def _cell_spans(p: Any, settings: Any) -> float:
    import numpy as np

    from fricenv.sweep import plan_cells

    plan = plan_cells(p, np.array([p.nu]), settings)
    return float(plan.t_transient[0] + plan.t_segment[0] * plan.n_segment[0]
                 * max(plan.tries[0], 1))


def _cell_statistics(params: list[dict], settings: dict | None = None) -> list[str]:
    import fricenv

    ps = [_params(d) for d in params]
    s = fricenv.SweepSettings(**(settings or {}))
    labels, stats, _, status = fricenv.cell_statistics(ps, s)
    return judge_cells(labels, stats, status, ps, s.x0, s.v0, [_cell_spans(p, s) for p in ps])


def _regime_map(params: dict, u0: list, nu: list, settings: dict | None = None,
                save: bool = False) -> list[str]:
    import fricenv

    base = _params(params)
    s = fricenv.SweepSettings(**(settings or {}))
    with tempfile.TemporaryDirectory() as tmp:
        m = fricenv.regime_map(base, u0, nu, settings=s, progress=False,
                               path=Path(tmp) / "m.npz" if save else None)
        if save:
            fricenv.RegimeMap.load(Path(tmp) / "m.npz")
    cells = [base.replace(u0=a, nu=b) for a in u0 for b in nu]
    return judge_cells(m.labels.ravel(), m.stats.reshape(-1, m.stats.shape[-1]),
                       m.status.ravel(), cells, s.x0, s.v0, [_cell_spans(p, s) for p in cells])


def _load(data: bytes) -> list[str]:
    import fricenv

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.npz"
        path.write_bytes(data)
        fricenv.RegimeMap.load(path)
    return []


def _env(env_id: str, make: dict, options: dict | None, actions: list, seed: int = 0,
         sample: int | None = None) -> list[str]:
    import gymnasium as gym
    import numpy as np

    import fricenv  # noqa: F401  (registers the ids)

    env = gym.make(env_id, **make)
    try:
        obs, _ = env.reset(seed=seed, options=options)
        wrong = [] if np.all(np.isfinite(obs)) else ["non-finite observation at reset"]
        if sample is not None:
            t, v, _ = env.unwrapped.sample_interval(np.asarray(actions[0], np.float32), sample)
            if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
                wrong.append("non-finite sample_interval")
            return wrong
        for a in actions:
            obs, r, term, trunc, info = env.step(np.asarray(a, np.float32))
            vals = [r, *info.values(), *np.asarray(obs, float).tolist()]
            if not all(math.isfinite(x) for x in vals):
                wrong.append(f"non-finite reward, info or observation: {r!r}, {info}")
                break
            if term or trunc:
                env.reset(options=options)
        return wrong
    finally:
        env.close()


def _vector(env_id: str, num_envs: int, make: dict, options: dict | None, steps: int,
            seed: int = 0) -> list[str]:
    import gymnasium as gym
    import numpy as np

    import fricenv  # noqa: F401

    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                        **make)
    try:
        obs, _ = venv.reset(seed=seed, options=options)
        wrong = [] if np.all(np.isfinite(obs)) else ["non-finite observation at reset"]
        venv.action_space.seed(seed)
        for _ in range(steps):
            obs, r, _, _, info = venv.step(venv.action_space.sample())
            if not (np.all(np.isfinite(r)) and np.all(np.isfinite(obs))):
                wrong.append("non-finite reward or observation")
                break
        return wrong
    finally:
        venv.close()


ENTRIES = {"simulate": _simulate, "run_stats": _run_stats, "cell_statistics": _cell_statistics,
           "regime_map": _regime_map, "load": _load, "env": _env, "vector": _vector}


def load_plugins(paths: list[str]) -> None:
    """Add the ``ENTRIES`` of each file in ``paths`` to :data:`ENTRIES` (entries of other
    callers, e.g. ``scripts/stress_entries.py``). A plugin's entry returns what is wrong with
    the answer (a list), or its own judgment, a dict with ``kind``, ``wrong`` and
    ``error``, when it has its own rule for which errors are clear."""
    import importlib.util

    for i, path in enumerate(paths):
        spec = importlib.util.spec_from_file_location(f"_callcheck_plugin{i}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        ENTRIES.update(module.ENTRIES)


def _answer(entry: str, kwargs: dict) -> dict:
    t0 = time.monotonic()
    try:
        wrong = ENTRIES[entry](**kwargs)
        if isinstance(wrong, dict):  # a plugin's own judgment
            return {**wrong, "seconds": time.monotonic() - t0}
        return {"kind": "returned", "seconds": time.monotonic() - t0, "wrong": wrong}
    except KeyboardInterrupt:
        return {"kind": "bare", "seconds": time.monotonic() - t0, "error": "KeyboardInterrupt"}
    except BaseException as e:  # noqa: BLE001  (judged, not handled)
        names = {c.__name__ for c in type(e).__mro__}
        kind = "clear" if names & set(DOCUMENTED) else "bare"
        if isinstance(e, OSError) and entry == "load":
            kind = "clear"  # a path that cannot be opened keeps its OSError
        return {"kind": kind, "seconds": time.monotonic() - t0,
                "error": f"{type(e).__name__}: {str(e)[:300]}"}


def serve() -> None:
    """The worker loop: length-prefixed pickles in on stdin, out on the original stdout."""
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # anything the calls print goes to stderr, not into the replies
    src = sys.stdin.buffer

    def send(obj: Any) -> None:
        data = pickle.dumps(obj)
        out.write(_HEADER.pack(len(data)) + data)
        out.flush()

    import gymnasium  # noqa: F401

    import fricenv  # noqa: F401

    load_plugins(sys.argv[1:])
    send("ready")
    while True:
        head = src.read(_HEADER.size)
        if len(head) < _HEADER.size:
            return
        entry, kwargs = pickle.loads(src.read(_HEADER.unpack(head)[0]))
        send(_answer(entry, kwargs))


if __name__ == "__main__":
    # Ctrl-C as Python's default, even when the parent was a background job, which starts
    # its children with SIGINT ignored: a hang's "Ctrl-C honoured" would read as ignored.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if p != here]  # the fricenv of PYTHONPATH only
    serve()
