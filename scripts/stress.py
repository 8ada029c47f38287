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

The matrix (fixed seed, so two runs try the same calls): the three friction laws of Fig.
2 and extreme ones (b1, b3 up to +-1e12), lam from 0 to 1e6, eta, nu, u0, V and the
friction levels from 0 to 1e12, starting states up to +-1e12, spans up to 1e3, through
run_stats, simulate, cell_statistics, regime_map (grids up to 1e12, saved and loaded),
the environments (reset options, steps, sample_interval), the vector env, damaged map
files, huge sizes and two writers of one map; plus the reproducers of known defects.

Usage: ``python scripts/stress.py [--budget 10] [--cases 250] [--seed 0] [--json out]``;
``PYTHONPATH`` picks the fricenv under test (e.g. ``PYTHONPATH=/path/to/other/tree``).
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget", type=float, default=10.0, help="seconds per call")
    ap.add_argument("--cases", type=int, default=250, help="random parameter sets")
    ap.add_argument("--files", type=int, default=200, help="damaged map files")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, help="write every outcome here")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    calls = [*KNOWN_HANGS, *KNOWN_DEFECTS, *random_calls(rng, args.cases),
             *damaged_files(rng, args.files)]
    pythonpath = os.environ.get("PYTHONPATH")
    worker = Worker(pythonpath, WARM_UP)
    results: list[tuple[str, dict, Outcome]] = []
    t0 = time.monotonic()
    try:
        for i, (entry, kwargs) in enumerate(calls):
            out = worker.call(entry, kwargs, args.budget)
            results.append((entry, kwargs, out))
            if out.kind != "clear" and not out.ok:
                print(f"[{i}] {entry} {_short(kwargs)}: {out.kind} {out.wrong or out.error} "
                      f"({out.seconds:.1f} s"
                      + (f", Ctrl-C {'honoured' if out.sigint_s is not None else 'ignored'}"
                         if out.kind == "hang" else "") + ")", flush=True)
        results.append(("two_writers", {}, two_writers(pythonpath, args.budget)))
    finally:
        worker.close()
    _report(results, time.monotonic() - t0, args.json)


def _short(kwargs: dict) -> str:
    text = repr({k: (f"<{len(v)} bytes>" if isinstance(v, bytes) else
                     f"<{len(v)} values>" if isinstance(v, list) and len(v) > 8 else v)
                 for k, v in kwargs.items()})
    return text if len(text) < 240 else text[:230] + "...}"


def _report(results: list, seconds: float, json_path: Path | None) -> None:
    kinds = collections.Counter()
    per_entry: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for entry, _, out in results:
        kind = {"returned": "wrong result" if out.wrong else "sound", "clear": "clear error",
                "bare": "bare error", "hang": "hang", "crash": "crash"}[out.kind]
        kinds[kind] += 1
        per_entry[entry][kind] += 1
    hangs = [out for _, _, out in results if out.kind == "hang"]
    honoured = sum(out.sigint_s is not None for out in hangs)
    print(f"\ncalls tried: {len(results)} in {seconds:.0f} s")
    for kind in ("sound", "clear error", "bare error", "wrong result", "hang", "crash"):
        print(f"  {kind:13s} {kinds[kind]}")
    print(f"  (hangs: Ctrl-C honoured within 1 s in {honoured} of {len(hangs)})")
    print("per entry: " + "; ".join(f"{e} {dict(c)}" for e, c in sorted(per_entry.items())))
    if json_path is not None:
        json_path.write_text(json.dumps([
            {"entry": e, "call": _short(k), "kind": o.kind, "seconds": o.seconds,
             "wrong": o.wrong, "error": o.error, "sigint_s": o.sigint_s}
            for e, k, o in results], indent=1))


if __name__ == "__main__":
    main()
