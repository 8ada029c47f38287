"""Cold-start profile: what the first call of each public entry point costs, compilation
included, and which numba kernels that time goes to.

Each workload's first call runs in a fresh Python process (``PYTHONPATH=<tree>``) with an
empty numba cache of its own (``NUMBA_CACHE_DIR``), so every kernel it needs is compiled,
exactly as on a fresh install. The child measures the import of fricenv (numba included),
then the first call: wall time, CPU time (all threads) and the process's peak resident set
size, then the same call again, warm, in the same process. It records numba's
``numba:compile`` events throughout. Those fire only when numba really compiles (a load
from the cache fires none), as a START/END pair around each compilation, with the
compilations of the kernels it calls nested inside; each compilation's self time is its
span less the spans of the compilations directly inside it.

With two ``--tree`` (old, then new) each workload runs on both in turn and the tables
show both and new/old. ``--cache-dir DIR`` shares one cache among all children instead
(run twice with the same DIR: the second run compiles nothing); ``--inherit-cache`` uses
numba's cache as the environment gives it (a warm cache, where the package has run).

Usage: ``fricenv bench compile [--tree PATH [--tree PATH]] [--workloads NAME...]
[--repeat N] [--cache-dir DIR | --inherit-cache] [--json FILE]``. The children load this
file by its path, and it imports nothing of fricenv at its top, so that each child's import
of the tree under test is the one measured.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

SCRIPT = Path(__file__).resolve()
#: The folder holding the fricenv package this module belongs to (a checkout, or
#: site-packages): the tree measured when no ``--tree`` is given.
DEFAULT_TREE = SCRIPT.parents[2]
#: The package's logger (progress lines; the ``fricenv`` command prints them on stderr).
LOGGER = logging.getLogger("fricenv")
#: Scenes of ``fricenv.envs.ENV_IDS`` (fixed here, so that ``--help`` lists the workloads
#: without importing a tree; a child of a tree without the scene fails, naming it).
SCENES = ("paper", "self_excited", "stribeck", "viscous", "exponential")
SIMULATE_METHODS = ("exact", "event", "rk4")  # fricenv.layout.METHODS
MAP_LAWS = ("coulomb", "viscous", "stribeck", "exponential")
VECTOR_PLANTS = 16
#: Kernels listed in the compile-time table.
TOP_KERNELS = 10
#: Lines of a failed child's stderr shown in the report.
STDERR_LINES = 20
#: A cold child compiles for a minute or two on a loaded 2-core machine; far beyond that,
#: it hangs.
CHILD_TIMEOUT_S = 1800.0
#: Marks the child's result line on its stdout, which warnings or prints may share.
RESULT_TAG = "bench-compile-result: "
#: Time spans of the workloads: long enough to cross switches, short enough that the warm
#: call takes milliseconds.
SIM_SPAN = 20.0
MAP_SPAN = 20.0
MIB = 1024 * 1024

WORKLOADS: dict[str, str] = {
    **{f"env-{s}": f"first step of gymnasium.make of the {s} scene's env" for s in SCENES},
    "vector16": f"first step of the native vector env, {VECTOR_PLANTS} plants, paper scene",
    **{f"simulate-{m}": f"fricenv.simulate, method {m!r}" for m in SIMULATE_METHODS},
    "run_stats": "fricenv.run_stats, Coulomb law",
    **{f"map-{law}": f"3 x 3 fricenv.regime_map, {law} law" for law in MAP_LAWS},
    "atlas": "one chunk of fricenv.atlas, 2 x 2 cells, into a Zarr store",
    "mpc": "one MPC decision: 256 x 12 batch rollout, self-excited scene",
}

# Metrics of a run: key, column title, format.
METRICS: tuple[tuple[str, str, str], ...] = (
    ("import_s", "import s", "{:.2f}"),
    ("first_s", "first call s", "{:.2f}"),
    ("cpu_s", "CPU s", "{:.2f}"),
    ("rss_mb", "peak RSS MB", "{:.0f}"),
    ("warm_ms", "warm ms", "{:.2f}"),
    ("compiles", "compiles", "{:.0f}"),
    ("compile_s", "compile s", "{:.2f}"),
)


# -- compile events: pairing, self time, totals (pure functions) --------------------------
@dataclass(frozen=True)
class Compile:
    """One compilation: a dispatcher (``module.qualname``) for one signature."""

    name: str
    sig: str
    start: float
    inclusive: float  # END - START
    self_time: float  # inclusive less the compilations directly inside it
    depth: int  # compilations open around it
    outermost: bool  # no compilation of the same dispatcher around it (recursion)
    phase: str = ""


def pair_compiles(events: Sequence[Mapping[str, Any]]) -> list[Compile]:
    """Pair START/END events (dicts with ``t``, ``kind`` "start"/"end", ``name``, ``sig``
    and optionally ``phase``) into compilations, in the order they started.

    numba fires them around each compilation, nested when compiling one kernel compiles
    those it calls; an END closes the innermost open START, which must be of the same
    dispatcher and signature (``ValueError`` otherwise, and for an END without START or a
    START never closed)."""
    out: list[Compile | None] = []
    stack: list[tuple[Mapping[str, Any], int, list[float]]] = []  # event, slot, children
    for ev in events:
        kind = ev.get("kind")
        if kind == "start":
            stack.append((ev, len(out), [0.0]))
            out.append(None)
        elif kind == "end":
            if not stack:
                raise ValueError(f"END of {ev['name']} {ev['sig']} with no START open")
            start, slot, children = stack.pop()
            if (start["name"], start["sig"]) != (ev["name"], ev["sig"]):
                raise ValueError(f"END of {ev['name']} {ev['sig']} inside the compilation "
                                 f"of {start['name']} {start['sig']}")
            inclusive = float(ev["t"]) - float(start["t"])
            if stack:
                stack[-1][2][0] += inclusive
            out[slot] = Compile(
                name=start["name"], sig=start["sig"], start=float(start["t"]),
                inclusive=inclusive, self_time=inclusive - children[0], depth=len(stack),
                outermost=all(e["name"] != start["name"] for e, _, _ in stack),
                phase=str(start.get("phase", "")))
        else:
            raise ValueError(f"event kind must be 'start' or 'end', got {kind!r}")
    if stack:
        ev = stack[-1][0]
        raise ValueError(f"START of {ev['name']} {ev['sig']} never ended")
    return [c for c in out if c is not None]


def compile_summary(compiles: Iterable[Compile]) -> tuple[int, float]:
    """Number of compilations and the time spent compiling (outermost spans only, so
    nested compilations are not counted twice)."""
    items = list(compiles)
    return len(items), sum(c.inclusive for c in items if c.depth == 0)


@dataclass
class KernelTotal:
    """A dispatcher's compilations over all workloads."""

    name: str
    self_s: float = 0.0
    inclusive_s: float = 0.0
    compiles: float = 0.0  # signatures compiled, per run
    workloads: set[str] = field(default_factory=set)


def kernel_totals(by_workload: Mapping[str, Iterable[Compile]],
                  runs: int = 1) -> list[KernelTotal]:
    """Per dispatcher: self and inclusive time and compilations per run (divided by
    ``runs``, the repeats pooled in ``by_workload``), and the workloads that compiled it;
    largest self time first. A recursive compilation's inclusive time counts once, at its
    outermost level."""
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs!r}")
    totals: dict[str, KernelTotal] = {}
    for workload, compiles in by_workload.items():
        for c in compiles:
            k = totals.setdefault(c.name, KernelTotal(c.name))
            k.self_s += c.self_time
            k.inclusive_s += c.inclusive if c.outermost else 0.0
            k.compiles += 1
            k.workloads.add(workload)
    for k in totals.values():
        k.self_s /= runs
        k.inclusive_s /= runs
        k.compiles /= runs
    return sorted(totals.values(), key=lambda k: (-k.self_s, k.name))


# -- tables ----------------------------------------------------------------------------------
def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]],
                   numeric_from: int = 1) -> str:
    """A markdown table; columns from ``numeric_from`` on are right-aligned."""
    rule = ["---" if i < numeric_from else "---:" for i in range(len(header))]
    lines = [header, rule, *rows]
    return "\n".join("| " + " | ".join(str(c) for c in line) + " |" for line in lines)


def _ratio(old: float, new: float) -> str:
    return f"{new / old:.2f}" if old > 0 else "–"


def results_table(cells: Mapping[str, Mapping[str, Mapping[str, float] | None]],
                  labels: Sequence[str]) -> str:
    """One row per workload: each metric per tree (``labels``: tree labels in order; a
    cell of None is a failed run) and, with two trees, new/old after each metric."""
    header = ["workload"]
    for _, title, _ in METRICS:
        if len(labels) == 1:
            header.append(title)
        else:
            header += [f"{title} ({labels[0]})", f"{title} ({labels[1]})",
                       f"{title} {labels[1]}/{labels[0]}"]
    rows = []
    for workload, by_tree in cells.items():
        row = [workload]
        for key, _, fmt in METRICS:
            values = [by_tree.get(label) for label in labels]
            row += ["failed" if v is None else fmt.format(v[key]) for v in values]
            if len(labels) == 2:
                old, new = values
                row.append("–" if old is None or new is None else _ratio(old[key], new[key]))
        rows.append(row)
    return markdown_table(header, rows)


def top_table(totals: Sequence[KernelTotal], n: int = TOP_KERNELS) -> str:
    """The ``n`` kernels with the largest compile self time."""
    rows = [[str(i), f"`{k.name}`", f"{k.self_s:.2f}", f"{k.inclusive_s:.2f}",
             f"{k.compiles:g}", str(len(k.workloads))]
            for i, k in enumerate(totals[:n], 1)]
    return markdown_table(["#", "kernel", "self s", "inclusive s", "compiles", "workloads"],
                          rows, numeric_from=2)


# -- the child: one workload, cold then warm ---------------------------------------------------
def _params(law: str) -> Any:
    import fricenv

    return fricenv.OscillatorParams.preset(law)


def _env_workload(scene: str) -> Callable[[Path], None]:
    def run(tmp: Path) -> None:
        import gymnasium as gym
        import numpy as np

        from fricenv.envs import ENV_IDS

        ids = [env_id for env_id, s in ENV_IDS.items() if s == scene]
        if not ids:
            raise ValueError(f"scene {scene!r} is not in fricenv.envs.ENV_IDS of this tree")
        env = gym.make(ids[0])
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, dtype=env.action_space.dtype))
        env.close()

    return run


def _vector(tmp: Path) -> None:
    import numpy as np

    from fricenv.envs.vector import StickSlipVectorEnv

    env = StickSlipVectorEnv(num_envs=VECTOR_PLANTS, scene="paper")
    env.reset(seed=0)
    env.step(np.zeros_like(env.action_space.sample()))
    env.close()


def _simulate_workload(method: str) -> Callable[[Path], None]:
    law = "coulomb" if method == "exact" else "stribeck"  # exact: Coulomb law only

    def run(tmp: Path) -> None:
        import fricenv

        fricenv.simulate(_params(law), SIM_SPAN, method=method)

    return run


def _run_stats(tmp: Path) -> None:
    import fricenv

    fricenv.run_stats(_params("coulomb"), SIM_SPAN)


def _small_settings() -> Any:
    import fricenv

    return fricenv.SweepSettings(transient_min=MAP_SPAN, transient_periods=0.0,
                                 transient_efolds=0.0, window_min=MAP_SPAN,
                                 window_periods=0.0, lock_extensions=0)


def _map_workload(law: str) -> Callable[[Path], None]:
    def run(tmp: Path) -> None:
        import fricenv

        fricenv.regime_map(law, u0=[0.5, 1.5, 5.0], nu=[0.5, 1.0, 2.0],
                           settings=_small_settings(), progress=False)

    return run


def _atlas(tmp: Path) -> None:
    from fricenv.atlas import atlas  # fricenv.atlas, the callable package

    atlas("coulomb", {"u0": [0.5, 2.0], "nu": [0.5, 1.0]}, path=tmp / "a.zarr",
          chunks=4, settings=_small_settings(), progress=False)


def _mpc(tmp: Path) -> None:
    """What one MPC (MPPI) decision computes: 256 action sequences of 12 intervals rolled
    out from one plant state (``fricenv.envs.rollout``, the batch rollout the agents' MPPI
    controller calls), so the library measures it without importing the agents."""
    import numpy as np

    from fricenv.envs.rollout import rollout_batch
    from fricenv.envs.stick_slip import StickSlipEnv

    env = StickSlipEnv(scene="self_excited")
    env.reset(seed=0)
    n_act = env.action_space.shape[0]  # type: ignore[index]
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (256, 12, n_act))
    rollout_batch(env, env.get_state(), actions)
    env.close()


RUNNERS: dict[str, Callable[[Path], None]] = {
    **{f"env-{s}": _env_workload(s) for s in SCENES},
    "vector16": _vector,
    **{f"simulate-{m}": _simulate_workload(m) for m in SIMULATE_METHODS},
    "run_stats": _run_stats,
    **{f"map-{law}": _map_workload(law) for law in MAP_LAWS},
    "atlas": _atlas,
    "mpc": _mpc,
}


def peak_rss_mb() -> float:
    """This process's peak resident set size. Linux: ``VmHWM``, as ``ru_maxrss`` keeps the
    high-water mark of the process that started this one (``subprocess`` uses vfork, and
    exec records the old address space's peak into the new process's ``ru_maxrss``)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024 / MIB
    except OSError:
        pass
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB; bytes on macOS
    return peak / MIB if sys.platform == "darwin" else peak * 1024 / MIB


def _event_record(ts: float, ev: Any, phase: str) -> dict[str, Any]:
    func = ev.data["dispatcher"].py_func
    return {"t": ts, "kind": "start" if ev.is_start else "end",
            "name": f"{func.__module__}.{func.__qualname__}", "sig": str(ev.data["args"]),
            "failed": bool(ev.is_end and ev.is_failed), "phase": phase}


def child_main(name: str, tree: str) -> None:
    """Run workload ``name`` cold, then warm; print one tagged JSON line."""
    run = RUNNERS[name]
    tmp = Path(tempfile.mkdtemp(prefix="bench-compile-"))
    try:
        t0 = time.perf_counter()
        from numba.core import event

        with event.install_recorder("numba:compile") as rec:
            import fricenv

            import_s = time.perf_counter() - t0
            n_import = len(rec.buffer)
            where = Path(fricenv.__file__).resolve()
            if not where.is_relative_to(Path(tree).resolve()):
                raise RuntimeError(f"fricenv imported from {where}, not from the tree {tree}")
            c0, t1 = time.process_time(), time.perf_counter()
            run(tmp / "first")
            first_s, cpu_s = time.perf_counter() - t1, time.process_time() - c0
            rss_mb = peak_rss_mb()
            n_first = len(rec.buffer)
            t2 = time.perf_counter()
            run(tmp / "warm")
            warm_ms = (time.perf_counter() - t2) * 1e3
        phases = ["import"] * n_import + ["first"] * (n_first - n_import)
        phases += ["warm"] * (len(rec.buffer) - n_first)
        events = [_event_record(ts, ev, ph) for (ts, ev), ph in zip(rec.buffer, phases,
                                                                     strict=True)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out = {"workload": name, "fricenv": str(where), "import_s": import_s, "first_s": first_s,
           "cpu_s": cpu_s, "rss_mb": rss_mb, "warm_ms": warm_ms, "events": events}
    print(RESULT_TAG + json.dumps(out), flush=True)


# -- the parent: arguments, children, report -------------------------------------------------
_CHILD_CODE = (
    "import importlib.util, sys\n"
    "spec = importlib.util.spec_from_file_location('bench_compile_child', {path!r})\n"
    "mod = importlib.util.module_from_spec(spec)\n"
    "sys.modules['bench_compile_child'] = mod\n"
    "spec.loader.exec_module(mod)\n"
    "mod.child_main(sys.argv[1], sys.argv[2])\n"
)


def _tree(value: str) -> Path:
    path = Path(value).expanduser().resolve()
    if not (path / "fricenv" / "__init__.py").is_file():
        raise argparse.ArgumentTypeError(f"{value!r} is not a checkout of fricenv "
                                         "(no fricenv/__init__.py in it)")
    return path


def _positive_int(value: str) -> int:
    try:
        n = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {value!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {value!r}")
    return n


def _positive_float(value: str) -> float:
    try:
        x = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {value!r}") from None
    if not x > 0 or x == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {value!r}")
    return x


def parse_args(argv: Sequence[str] | None = None, prog: str | None = None
               ) -> argparse.Namespace:
    """Parse and check every option before anything runs (exit 2 naming the option)."""
    ap = argparse.ArgumentParser(
        prog=prog, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Cold start: the first call of each entry point in a fresh process, "
                    "and numba's compile time by kernel.",
        epilog="workloads:\n" + "\n".join(f"  {k:<17} {v}" for k, v in WORKLOADS.items())
        + "\n\nexample:\n  fricenv bench compile --workloads simulate-exact map-coulomb")
    ap.add_argument("--tree", action="append", type=_tree, metavar="PATH",
                    help="the folder holding the fricenv to measure (default: this one's); "
                         "twice: old, then new, side by side")
    ap.add_argument("--workloads", nargs="+", choices=list(WORKLOADS), metavar="NAME",
                    help="workloads to run (default: all; listed below)")
    ap.add_argument("--repeat", type=_positive_int, default=1, metavar="N",
                    help="runs of each workload per tree; the tables show medians")
    cache = ap.add_mutually_exclusive_group()
    cache.add_argument("--cache-dir", metavar="DIR",
                       help="numba cache shared by all children (created if missing), "
                            "instead of a fresh empty one each")
    cache.add_argument("--inherit-cache", action="store_true",
                       help="use numba's cache as the environment sets it (warm)")
    ap.add_argument("--json", metavar="FILE", help="save the raw results to FILE")
    ap.add_argument("--timeout", type=_positive_float, default=CHILD_TIMEOUT_S, metavar="S",
                    help=f"seconds a child may take (default: {CHILD_TIMEOUT_S:g})")
    args = ap.parse_args(argv)
    args.tree = args.tree or [DEFAULT_TREE]
    if len(args.tree) > 2:
        ap.error(f"argument --tree: at most two trees (old, new), got {len(args.tree)}")
    if len(set(args.tree)) != len(args.tree):
        ap.error(f"argument --tree: the same tree twice: {args.tree[0]}")
    args.workloads = list(dict.fromkeys(args.workloads or WORKLOADS))
    if args.cache_dir is not None:
        args.cache_dir = Path(args.cache_dir).expanduser().resolve()
        if args.cache_dir.exists() and not args.cache_dir.is_dir():
            ap.error(f"argument --cache-dir: {args.cache_dir} is a file, not a folder")
    if args.json is not None:
        path = Path(args.json).expanduser()
        if path.is_dir():
            ap.error(f"argument --json: {args.json!r} is a folder, not a file")
        if not path.resolve().parent.is_dir():
            ap.error(f"argument --json: the folder of {args.json!r} does not exist")
        args.json = path
    return args


def _tail(text: str, n: int = STDERR_LINES) -> str:
    return "\n".join(text.rstrip().splitlines()[-n:])


def run_child(name: str, tree: Path, cache_dir: Path | None, inherit: bool,
              timeout: float) -> dict[str, Any]:
    """One workload in a fresh process on ``tree``: its result, or ``{"failed": True,
    "error": ...}``. ``cache_dir`` None (and not ``inherit``): a fresh empty cache."""
    work = Path(tempfile.mkdtemp(prefix="bench-compile-"))
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONUNBUFFERED="1")
    if not inherit:
        env["NUMBA_CACHE_DIR"] = str(cache_dir or work / "numba-cache")
    try:  # cwd: a folder holding no fricenv, which `-c` would put first on sys.path
        proc = subprocess.run([sys.executable, "-c", _CHILD_CODE.format(path=str(SCRIPT)),
                               name, str(tree)], cwd=work, env=env, capture_output=True,
                              text=True, timeout=timeout)
    except subprocess.TimeoutExpired as e:
        err = e.stderr.decode(errors="replace") if isinstance(e.stderr, bytes) else e.stderr
        return {"failed": True, "error": f"timed out after {timeout:g} s\n{_tail(err or '')}"}
    finally:
        shutil.rmtree(work, ignore_errors=True)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_TAG)]
    if proc.returncode != 0 or not lines:
        return {"failed": True, "error": f"exit status {proc.returncode}\n{_tail(proc.stderr)}"}
    result: dict[str, Any] = json.loads(lines[-1][len(RESULT_TAG):])
    compiles = pair_compiles(result["events"])
    cold = [c for c in compiles if c.phase != "warm"]
    result["compiles"], result["compile_s"] = compile_summary(cold)
    result["warm_compiles"] = sum(1 for c in compiles if c.phase == "warm")
    result["failed"] = False
    return result


def tree_labels(trees: Sequence[Path]) -> list[str]:
    return ["tree"] if len(trees) == 1 else ["old", "new"]


def collect(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Every run, workloads alternating between the trees; a progress line each (the
    ``fricenv`` logger)."""
    labels = tree_labels(args.tree)
    if args.cache_dir is not None:
        args.cache_dir.mkdir(parents=True, exist_ok=True)
    runs: list[dict[str, Any]] = []
    total = args.repeat * len(args.workloads) * len(args.tree)
    for rep in range(args.repeat):
        for name in args.workloads:
            for label, tree in zip(labels, args.tree, strict=True):
                where = f"[{len(runs) + 1}/{total}] {name} ({label})"
                LOGGER.info(f"{where}: running in a fresh process")
                r = run_child(name, tree, args.cache_dir, args.inherit_cache, args.timeout)
                r.update(workload=name, tree=str(tree), label=label, repeat=rep)
                LOGGER.info(f"{where}: " + ("FAILED" if r["failed"] else
                            f"{r['first_s']:.1f} s, {r['compiles']} compiles"))
                runs.append(r)
    return runs


def medians(runs: Sequence[Mapping[str, Any]], workloads: Sequence[str],
            labels: Sequence[str]) -> dict[str, dict[str, dict[str, float] | None]]:
    """Median of each metric per workload and tree; None where any run failed."""
    cells: dict[str, dict[str, dict[str, float] | None]] = {}
    for name in workloads:
        cells[name] = {}
        for label in labels:
            mine = [r for r in runs if r["workload"] == name and r["label"] == label]
            cells[name][label] = (None if not mine or any(r["failed"] for r in mine) else
                                  {k: statistics.median(r[k] for r in mine)
                                   for k, _, _ in METRICS})
    return cells


def report(runs: Sequence[Mapping[str, Any]], args: argparse.Namespace) -> str:
    """The markdown report: the per-workload table, the top kernels per tree, failures."""
    labels = tree_labels(args.tree)
    cache = ("numba's cache from the environment" if args.inherit_cache else
             "a fresh empty numba cache per child" if args.cache_dir is None else
             f"the numba cache {args.cache_dir}")
    trees = ", ".join(f"{lb} = {t}" for lb, t in zip(labels, args.tree, strict=True))
    out = [f"Trees: {trees}; {cache}; median of {args.repeat} run(s).", "",
           results_table(medians(runs, args.workloads, labels), labels)]
    for label in labels:
        ok = [r for r in runs if r["label"] == label and not r["failed"]]
        by_workload: dict[str, list[Compile]] = {}
        for r in ok:
            by_workload.setdefault(r["workload"], []).extend(
                c for c in pair_compiles(r["events"]) if c.phase != "warm")
        title = "" if len(labels) == 1 else f" ({label})"
        out += ["", f"Top {TOP_KERNELS} kernels by compile self time{title}, seconds per "
                "run, summed over the workloads (compiles: signatures compiled per run; "
                "workloads: how many compiled it):", "",
                top_table(kernel_totals(by_workload, args.repeat))]
        warm = sorted({r["workload"] for r in ok if r["warm_compiles"]})
        if warm:
            out += ["", f"Compiled again in the warm call{title}: {', '.join(warm)}"]
    for r in runs:
        if r["failed"]:
            out += ["", f"FAILED: {r['workload']} ({r['label']}, {r['tree']}):", "```",
                    r["error"], "```"]
    return "\n".join(out)


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    """Run the profile; the exit status is 1 when a workload failed."""
    args = parse_args(argv, prog)
    runs = collect(args)
    print(report(runs, args))
    if args.json is not None:
        raw = {"trees": [str(t) for t in args.tree], "labels": tree_labels(args.tree),
               "workloads": args.workloads, "repeat": args.repeat,
               "cache": str(args.cache_dir) if args.cache_dir else
               ("inherit" if args.inherit_cache else "fresh"), "runs": runs}
        args.json.write_text(json.dumps(raw, indent=1))
    return 1 if any(r["failed"] for r in runs) else 0


if __name__ == "__main__":
    sys.exit(main())
