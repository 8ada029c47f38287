"""Stress matrix: every public entry point, with parameters, starting states and grids up to
the documented limits, and counts of how the calls end.

Each call runs in a worker process (``tests/callcheck.py``) with a time budget (10 s by
default, the bound on every call); a call over it is a *hang* (then SIGINT is sent, and
whether the worker answers within a second is recorded: Ctrl-C honoured or not). The
others end as

* *sound*: an answer with nothing wrong in it;
* *clear error*: a documented exception (TypeError, ValueError, RuntimeError and its
  subclasses SimulationError, MapInUseError, ResetNeeded);
* *bare error*: any other exception (EOFError, MemoryError, BadZipFile...);
* *wrong result*: an answer with a statistic inf or NaN under status OK, motion beyond the
  bound of ``fricenv.divergence`` presented as a result, a stick time above its duration,
  a block stuck all window long labelled as stick-slip; two writers of one map both
  accepted;
* *crash*: the worker died.

The matrix (fixed seed, so two runs try the same calls), by class (``--classes``):

* ``reproducers``: the known defects' reproducers;
* ``random``: the three friction laws of Fig. 2 and extreme ones (b1, b3 up to +-1e12),
  lam from 0 to 1e6, eta, nu, u0, V and the friction levels from 0 to 1e12, starting
  states up to +-1e12, spans up to 1e3, through run_stats, simulate, cell_statistics,
  regime_map (grids up to 1e12, saved and loaded), the environments (reset options, steps,
  sample_interval) and the vector env;
* ``map files``: damaged map files; ``writers``: two writers of one map;

and the later classes (``stress_probes.py``; worker entries in ``stress_entries.py``),
each judged through the public API and its observable effects only:

* ``threads``: regime_map, cell_statistics and 64-plant vector envs in two threads of
  one fresh process (sound: no crash, the serial run's results), and a fork pool after a
  parallel kernel ran;
* ``signals``: SIGINT 2 s into a one-chunk Stribeck regime_map (100 x 100), a one-chunk
  atlas and a 10^3-cell cell_statistics (cells with long windows, ~10 s each sweep),
  SIGTERM into a regime_map with 500-cell chunks:
  a hang if the process has not exited 2 s after the signal, wrong if it exits keeping
  none of the cells it had finished (the map file or store holds none after 2 s of
  computing, or fewer than the callback reported);
* ``damage``: copies of a small atlas store with a bit flipped in a chunk of each
  variable, a chunk deleted, a coordinate flipped, a ``zarr.json`` truncated, invalid or
  reshaped, opened and resumed (wrong: values unlike the undamaged store's, with no
  error; bare: an error that does not name the store, e.g. Zstd's RuntimeError or a
  JSONDecodeError); a second atlas writer on a store being written;
* ``huge``: atlases of 10^12 to 10^14 cells (clear: a prompt ValueError; hang otherwise);
* ``set_state``: env states with a stuck block off the belt speed, v = +-1e300,
  x = 1e13, xfs = 1e300, t = 1e17, garbage in the workspace, then stepped (wrong: accepted
  and the steps raise or disagree with a fresh reset to that plant and state, the time
  does not advance, or a value is non-finite);
* ``points``: simulate with 1.2e7 and 1e8 output points, or from t0 = 1e15 (wrong:
  output times not strictly increasing, or a SimulationError that blames stiffness on
  this non-stiff plant; bare: MemoryError);
* ``tampered``: map files rewritten by the package's own ``save`` with inf or NaN
  statistics, a negative period, an unknown status or label, loaded and resumed (wrong:
  loaded, or the tampered values kept);
* ``unclear``: one bad argument each (a short state array, a NaN mode, a ``.npy`` file
  as a map, ``render_mode=5``): bare if the error does not name it;

and the edge classes (``stress_edges.py``: each case in a fresh interpreter of the tree
under test): ``statistics`` (NaN scores and strata, bad arguments of the agents'
statistics), ``settings`` (a periodicity test its settings switch off), ``stored``
(atlas chunks out of place, a map's labels against its statistics, symlinked maps),
``cache`` (each kind of damage to numba's cache files; no writable cache location),
``stops`` (Ctrl-C on a Dask atlas to the client and to the process group, SIGTERM into
``fricenv train``, worker counts below 1) and ``smaller`` (NaN in ``set_state``'s delay
line and noise, ``simulate --out`` under a file, Ctrl-C on ``map`` / ``atlas`` /
``reproduce``, a damaged model file, ``warmup``'s arguments, a repeated ``--axis``).

Usage: ``python scripts/stress.py [--budget 10] [--cases 250] [--seed 0] [--classes a,b]
[--json out]``; ``PYTHONPATH`` picks the fricenv under test (e.g.
``PYTHONPATH=/path/to/other/tree``), in this process and in every process it starts.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import stress_edges as edges  # noqa: E402
import stress_probes as probes  # noqa: E402
from callcheck import WARM_UP, Outcome, Worker  # noqa: E402

LAMS = [0.0, 1e-12, 0.05, 0.5, 2.0, 50.0, 1e3, 1e6]
LAWS = [(0.0, 0.0), (0.2, 0.0), (0.2, 0.16)]
EXTREME_LAWS = [(1e12, 1e12), (1e6, 1e6), (1.0, 0.0), (0.0, -1.0), (-1e12, 1e12), (0.2, 1e-12)]
ETAS = [1e-3, 0.2, 0.6, 7 / 3, 1e3, 1e12]
NUS = [0.0, 0.1, 0.95, 1.0, 2.0, 1e3, 1e12]
AMPS = [0.0, 1e-12, 0.2, 2.0, 20.0, 1e6, 1e12]
SPEEDS = [0.0, 1.0, 1e3, 1e12]
FRICTION = [(2.5, 4.0), (0.0, 0.0), (2.5, 2.5), (1e12, 1e12), (0.0, 1e12)]
STATES = [0.0, 1.0, -1e6, 1e12, -1e12]
SPANS = [3.8, 100.0, 1e3]
ENV_IDS = ["fricenv/StickSlip-v0", "fricenv/StickSlipSelfExcited-v0"]

#: Reproducers of defects that need the kernels to honour a step budget: they hang.
KNOWN_HANGS = [
    ("run_stats", {"params": {"b1": 1e12, "b3": 1e12, "u0": 5.0, "nu": 1.0}, "t_span": 3.8}),
    ("simulate", {"params": {"b1": 1e12, "b3": 1e12, "u0": 5.0, "nu": 1.0}, "t_end": 3.8}),
    ("env", {"env_id": "fricenv/StickSlipSelfExcited-v0", "make": {},
             "options": {"b1": 1e12, "b3": 1e12}, "actions": [[0.0, 0.0]]}),
    ("env", {"env_id": "fricenv/StickSlip-v0", "make": {},
             "options": {"x0": 1e12, "b1": 0.2, "b3": 0.16}, "actions": [[0.0]]}),
]
#: Reproducers of the other defects found by the first stress run.
KNOWN_DEFECTS = [
    ("run_stats", {"params": {"lam": 0.0, "b1": 1.0, "u0": 10.0, "nu": 0.3}, "t_span": 1e3}),
    ("simulate", {"params": {"lam": 0.0, "b1": 1.0, "u0": 10.0, "nu": 0.3}, "t_end": 1e3}),
    ("regime_map", {"params": {"lam": 0.5, "b1": 2.0}, "u0": [1.0], "nu": [0.3]}),
    ("cell_statistics", {"params": [{"V": 0.0, "u0": 1.0, "nu": nu} for nu in (0.5, 1.0, 2.0)]}),
    ("load", {"data": b""}),
    ("vector", {"env_id": ENV_IDS[0], "num_envs": 10**12, "make": {}, "options": None,
                "steps": 1}),
    ("env", {"env_id": ENV_IDS[0], "make": {}, "options": None, "actions": [[0.0]],
             "sample": 10**10}),
    ("env", {"env_id": ENV_IDS[0], "make": {}, "options": {"lam": 0.0, "b1": 685.5031072611627},
             "actions": [[0.0]]}),
    ("regime_map", {"params": {}, "u0": list(np.linspace(0, 1, 100_000)),
                    "nu": list(np.linspace(0, 2, 100_000))}),
]


def random_params(rng: np.random.Generator) -> dict:
    pick = rng.choice
    b1, b3 = LAWS[rng.integers(3)] if rng.random() < 0.7 else EXTREME_LAWS[
        rng.integers(len(EXTREME_LAWS))]
    xfk, xfs = FRICTION[rng.integers(len(FRICTION))] if rng.random() < 0.4 else (2.5, 4.0)
    return {"lam": float(pick(LAMS)), "eta": float(pick(ETAS)) if rng.random() < 0.5 else 0.6,
            "nu": float(pick(NUS)), "u0": float(pick(AMPS)),
            "V": float(pick(SPEEDS)) if rng.random() < 0.4 else 1.0,
            "xfk": xfk, "xfs": xfs, "b1": b1, "b3": b3}


def random_calls(rng: np.random.Generator, n: int) -> list[tuple[str, dict]]:
    calls = []
    for _ in range(n):
        p = random_params(rng)
        start = (float(rng.choice(STATES)), float(rng.choice(STATES))) if rng.random() < 0.3 \
            else (0.0, 0.0)
        span = float(rng.choice(SPANS))
        calls.append(("run_stats", {"params": p, "t_span": span, "x0": start[0],
                                    "v0": start[1]}))
        r = rng.random()
        if r < 0.3:
            calls.append(("simulate", {"params": p, "t_end": min(span, 100.0), "x0": start[0],
                                       "v0": start[1]}))
        elif r < 0.55:
            calls.append(("cell_statistics", {"params": [p], "settings": {
                "x0": start[0], "v0": start[1]}}))
        elif r < 0.65:
            base = {k: v for k, v in p.items() if k not in ("u0", "nu")}
            calls.append(("regime_map", {"params": base, "u0": [0.0, 1.0, float(p["u0"])][
                : 3 if p["u0"] not in (0.0, 1.0) else 2], "nu": [0.5, 1.0], "save": True}))
        elif r < 0.9:
            options = {k: p[k] for k in ("lam", "eta", "V", "xfk", "xfs", "b1", "b3")}
            options.update(x0=start[0], v0=start[1])
            env_id = ENV_IDS[int(rng.integers(2))]
            n_act = 1 if env_id == ENV_IDS[0] else 2
            actions = rng.uniform(-1, 1, (5, n_act)).tolist()
            calls.append(("env", {"env_id": env_id, "make": {}, "options": options,
                                  "actions": actions,
                                  "sample": 64 if rng.random() < 0.2 else None}))
        else:
            calls.append(("vector", {"env_id": ENV_IDS[int(rng.integers(2))],
                                     "num_envs": int(rng.choice([1, 3, 70])),
                                     "make": {"randomize": bool(rng.random() < 0.5)},
                                     "options": None, "steps": 20}))
    return calls


def damaged_files(rng: np.random.Generator, n: int) -> list[tuple[str, dict]]:
    """Copies of a small map file with one byte changed, truncated, or empty."""
    import fricenv

    with tempfile.TemporaryDirectory() as tmp:
        path = fricenv.regime_map("coulomb", [0.5, 3.0], [0.5, 1.3], progress=False).save(
            Path(tmp) / "m.npz")
        good = path.read_bytes()
    calls = [("load", {"data": good[:k]}) for k in rng.integers(0, len(good), n // 4)]
    for k in rng.integers(0, len(good), n - n // 4):
        data = bytearray(good)
        data[k] = (data[k] + int(rng.integers(1, 256))) % 256
        calls.append(("load", {"data": bytes(data)}))
    return calls


_WRITER = textwrap.dedent("""
    import sys, time
    import fricenv
    def slow(rmap, n):
        print("running", flush=True)
        time.sleep(float(sys.argv[3]))
    fricenv.regime_map("coulomb", [float(sys.argv[2])], [0.5, 1.3], path=sys.argv[1],
                       chunk_size=1, callback=slow, progress=False)
""")


def two_writers(pythonpath: str | None, budget: float) -> Outcome:
    """A second sweep on a map path while a first one writes it, with other arguments:
    sound if one of them is refused with an error, wrong if both exit 0."""
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "m.npz")
        # (run from the temporary folder: "python -c" puts the current folder first on
        # the path, which would shadow the fricenv of PYTHONPATH)
        first = subprocess.Popen([sys.executable, "-c", _WRITER, path, "0.5", "2"], env=env,
                                 cwd=tmp, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                 text=True)
        first.stdout.readline()
        second = subprocess.run([sys.executable, "-c", _WRITER, path, "3.0", "0"], env=env,
                                cwd=tmp, capture_output=True, text=True, timeout=budget * 6)
        first.wait(timeout=budget * 6)
        first.stdout.close()
    seconds = time.monotonic() - t0
    if first.returncode == 0 and second.returncode == 0:
        return Outcome("returned", seconds, wrong=["both writers of one map exited 0"])
    err = second.stderr.strip().splitlines()[-1:] or [""]
    return Outcome("clear" if "Error" in err[0] else "bare", seconds, error=err[0])


#: The classes of calls, in the order they run (``--classes`` picks some).
CLASSES = ("reproducers", "random", "map files", "writers", "threads", "signals", "damage",
           "huge", "set_state", "points", "tampered", "unclear", *edges.EDGE_CLASSES)
ENTRIES_PLUGIN = Path(__file__).resolve().parent / "stress_entries.py"
#: Warm-up calls of the later classes (Dask, Zarr and xarray; the Stribeck env's kernels).
LATER_WARM_UP = [("atlas_warm", {}),
                 ("set_state", {"env_id": "fricenv/StickSlipStribeck-v0", "change": {"t": 1.0}})]


def worker_calls(classes: list[str], args: argparse.Namespace, rng: np.random.Generator,
                 tmp: Path) -> list[tuple[str, str, dict]]:
    """``(class, entry, kwargs)`` of every call that the worker makes. The random draws
    come first, in the order of the first matrix, whatever classes are picked, so that a
    seed tries the same calls."""
    random = random_calls(rng, args.cases)
    files = damaged_files(rng, args.files)
    picked = {
        "reproducers": [*KNOWN_HANGS, *KNOWN_DEFECTS], "random": random, "map files": files,
        "huge": probes.HUGE, "set_state": probes.SET_STATE, "points": probes.POINTS,
        "tampered": probes.TAMPERED, "unclear": probes.UNCLEAR,
    }
    if "damage" in classes:
        store = probes.build_atlas(tmp)
        picked["damage"] = probes.damage_calls(store, np.random.default_rng(args.seed),
                                               args.flips)
    return [(c, e, k) for c in classes if c in picked for e, k in picked[c]]


def process_probes(classes: list[str], pythonpath: str | None,
                   budget: float) -> list[tuple[str, str, dict, Outcome]]:
    """The probes that run in processes of their own."""
    out = []
    if "writers" in classes:
        out.append(("writers", "two_writers", {}, two_writers(pythonpath, budget)))
    if "threads" in classes:
        out += [("threads", *r) for r in probes.threads_class(pythonpath, budget)]
    if "signals" in classes:
        out += [("signals", *r) for r in probes.signal_class(pythonpath)]
    if "damage" in classes:
        out.append(("damage", "atlas_writers", {}, probes.atlas_writers(pythonpath, budget)))
    for cls, probe in edges.EDGE_CLASSES.items():
        if cls in classes:
            out += [(cls, name, {}, outcome) for name, outcome in probe(pythonpath, budget)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget", type=float, default=10.0, help="seconds per call")
    ap.add_argument("--cases", type=int, default=250, help="random parameter sets")
    ap.add_argument("--files", type=int, default=200, help="damaged map files")
    ap.add_argument("--flips", type=int, default=3, help="bit flips per atlas variable")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--classes", default=",".join(CLASSES),
                    help=f"comma-separated classes to run, of: {', '.join(CLASSES)}")
    ap.add_argument("--json", type=Path, help="write every outcome here")
    args = ap.parse_args()
    classes = [c.strip() for c in args.classes.split(",") if c.strip()]
    unknown = sorted(set(classes) - set(CLASSES))
    if unknown:
        ap.error(f"unknown classes {unknown}; pick of {', '.join(CLASSES)}")
    pythonpath = os.environ.get("PYTHONPATH")
    results: list[tuple[str, str, dict, Outcome]] = []
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        calls = worker_calls(classes, args, np.random.default_rng(args.seed), Path(tmp))
        later = any(c in classes for c in CLASSES[4:12])
        if calls:  # (the edge classes run in processes of their own only)
            worker = Worker(pythonpath, WARM_UP + (LATER_WARM_UP if later else []),
                            plugins=[ENTRIES_PLUGIN])
            try:
                for i, (cls, entry, kwargs) in enumerate(calls):
                    out = worker.call(entry, kwargs, args.budget)
                    results.append((cls, entry, kwargs, out))
                    _show(i, entry, kwargs, out)
            finally:
                worker.close()
        for cls, entry, kwargs, out in process_probes(classes, pythonpath, args.budget):
            results.append((cls, entry, kwargs, out))
            _show(len(results) - 1, entry, kwargs, out)
    _report(results, time.monotonic() - t0, args.json)


def _show(i: int, entry: str, kwargs: dict, out: Outcome) -> None:
    """Print a call that did not end soundly or with a clear error."""
    if out.kind != "clear" and not out.ok:
        print(f"[{i}] {entry} {_short(kwargs)}: {out.kind} {out.wrong or out.error} "
              f"({out.seconds:.1f} s"
              + (f", Ctrl-C {'honoured' if out.sigint_s is not None else 'ignored'}"
                 if out.kind == "hang" and entry != "signal" else "") + ")", flush=True)


#: Arguments left out of the printed calls (the same in every call of their class).
_UNSHOWN = ("good", "spec")


def _short(kwargs: dict) -> str:
    text = repr({k: (f"<{len(v)} bytes>" if isinstance(v, bytes) else
                     f"<{len(v)} values>" if isinstance(v, list) and len(v) > 8 else v)
                 for k, v in kwargs.items() if k not in _UNSHOWN})
    return text if len(text) < 240 else text[:230] + "...}"


KINDS = ("sound", "clear error", "bare error", "wrong result", "hang", "crash")


def _kind(out: Outcome) -> str:
    return {"returned": "wrong result" if out.wrong else "sound", "clear": "clear error",
            "bare": "bare error", "hang": "hang", "crash": "crash"}[out.kind]


def _report(results: list, seconds: float, json_path: Path | None) -> None:
    kinds: collections.Counter = collections.Counter()
    per_entry: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    per_class: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for cls, entry, _, out in results:
        kind = _kind(out)
        kinds[kind] += 1
        per_entry[entry][kind] += 1
        per_class[cls][kind] += 1
    hangs = [out for *_, out in results if out.kind == "hang"]
    honoured = sum(out.sigint_s is not None for out in hangs)
    print(f"\ncalls tried: {len(results)} in {seconds:.0f} s")
    for kind in KINDS:
        print(f"  {kind:13s} {kinds[kind]}")
    print(f"  (hangs: Ctrl-C honoured within 1 s in {honoured} of {len(hangs)})")
    print("per entry: " + "; ".join(f"{e} {dict(c)}" for e, c in sorted(per_entry.items())))
    print(f"\n{'class':12s}" + "".join(f"{k:>13s}" for k in KINDS))
    for cls in CLASSES:
        if cls in per_class:
            print(f"{cls:12s}" + "".join(f"{per_class[cls][k]:13d}" for k in KINDS))
    for cls, entry, _, out in results:  # (the edge classes' cases, one line each)
        if cls in edges.EDGE_CLASSES:
            print(f"  {cls:10s} {entry:36s} {_kind(out):13s} "
                  f"{'; '.join(out.wrong) or out.error}"[:200])
    if json_path is not None:
        json_path.write_text(json.dumps([
            {"class": c, "entry": e, "call": _short(k), "kind": o.kind, "seconds": o.seconds,
             "wrong": o.wrong, "error": o.error, "sigint_s": o.sigint_s}
            for c, e, k, o in results], indent=1))


if __name__ == "__main__":
    main()
