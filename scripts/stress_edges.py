"""The stress matrix's edge classes: what a second probe found held only in the middle of
the road (``scripts/stress.py --classes statistics,settings,stored,cache,stops,smaller``).

Each case runs in a fresh interpreter with ``PYTHONPATH`` choosing the fricenv under test
(and its ``agents/`` folder as ``fricenv_agents``), judged from its output, files and exit
only, so the same script measures any tree:

* ``statistics``: NaN scores and strata, a bad ``axis``, a string ``confidence``,
  ``n_boot=10**9``, an empty ``tau_grid`` (wrong: a number out of NaN, or two answers to
  one seeded call; bare: an error that does not name the argument);
* ``settings``: ``n_strobe`` below ``2 m_max + 1`` (wrong: the map returned with its
  periodicity test off in silence);
* ``stored``: atlas chunk files swapped between positions or variables or copied from
  another atlas, a map whose label contradicts its statistics, a second writer through a
  symlink, a save through a symlink (wrong: loaded as this atlas's cells, both writers
  accepted, the symlink replaced by a file);
* ``cache``: a package's numba cache with each kind of damage to its index and data files,
  and with no writable location, warm or empty (bare: an exception from the kernel's
  call; crash: a signal; wrong: the right result with nothing said about the damage);
* ``stops``: Ctrl-C on a Dask atlas, to the client alone and to the whole process group,
  SIGTERM into ``fricenv train``, ``--local-workers`` below 1 (hang: no exit within 2 s
  of the signal, 30 s for a training that saves its model, or no answer to a bad count
  within the budget; wrong: a plain
  ``KeyboardInterrupt`` or ``TimeoutError`` instead of ``SweepInterrupted``, no model
  saved);
* ``smaller``: NaN in ``set_state``'s delay line and noise stream, ``simulate --out``
  under a file, Ctrl-C on ``map`` / ``atlas`` / ``reproduce``, a damaged model file,
  ``warmup(parallel='no')`` and ``warmup(laws='coulomb')``, a repeated ``--axis``.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from callcheck import Outcome  # noqa: E402

#: Seconds a stopped run may take from the signal to its exit.
STOP_BOUND_S = 2.0

#: Prepended to every child: ``case(name, call, names, check)`` runs ``call()`` and prints
#: one ``CASE`` line judging it. An exception is *clear* if it is a TypeError, ValueError
#: or RuntimeError (or subclass) whose message contains ``names``, else *bare*; an answer
#: is *wrong* if ``check(answer)`` names something wrong.
_HEAD = textwrap.dedent("""
    import json, os, signal, sys, time
    import numpy as np
    signal.signal(signal.SIGINT, signal.default_int_handler)
    def case(name, call, names="", check=None):
        t0 = time.monotonic()
        try:
            answer = call()
        except BaseException as e:
            kinds = {c.__name__ for c in type(e).__mro__}
            clear = bool(kinds & {"TypeError", "ValueError", "RuntimeError"}) and names in str(e)
            out = {"kind": "clear" if clear else "bare", "wrong": [],
                   "error": f"{type(e).__name__}: {str(e)[:300]}"}
        else:
            wrong = check(answer) if check is not None else []
            out = {"kind": "returned", "wrong": list(wrong or []), "error": ""}
        out["seconds"] = time.monotonic() - t0
        print("CASE " + json.dumps({"name": name, **out}), flush=True)
    def cli(*argv):
        # a fricenv command in this process: its exit status, or ValueError with its
        # message for a usage error (what the user reads)
        import contextlib, io
        from fricenv.cli import main
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            try:
                code = main(list(argv))
            except SystemExit as e:
                code = e.code
        if code not in (0, None):
            raise ValueError(f"exit {code}: {err.getvalue().strip()[-400:]}")
        return code
""")


def _env(pythonpath: str | None, tmp: Path, **extra: str) -> dict:
    """The child's environment: ``pythonpath``'s fricenv and its ``agents/`` folder as
    ``fricenv_agents`` (a link in ``tmp``: an editable install would otherwise import the
    agents of whichever tree it was made from)."""
    env = {**os.environ, **extra}
    root = Path(pythonpath.split(os.pathsep)[0]) if pythonpath else Path(__file__).parents[1]
    shim = tmp / "shim"
    shim.mkdir(exist_ok=True)
    if not (shim / "fricenv_agents").exists():
        (shim / "fricenv_agents").symlink_to(root / "agents")
    env["PYTHONPATH"] = os.pathsep.join([str(shim), pythonpath or str(root)])
    return env


def run_cases(body: str, pythonpath: str | None, timeout: float, args: tuple = (),
              prefix: tuple = (), **extra: str) -> list[tuple[str, Outcome]]:
    """Run ``_HEAD + body`` in a fresh interpreter; one ``(name, Outcome)`` per ``CASE``
    line, and a *crash*, *hang* or *bare* outcome for the child itself if it ended
    otherwise than by finishing."""
    code = _HEAD + textwrap.dedent(body)
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        proc = subprocess.Popen([*prefix, sys.executable, "-c", code, str(tmp), *args],
                                env=_env(pythonpath, tmp, **extra), cwd=tmp, text=True,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                start_new_session=True)
        try:
            out, err = proc.communicate(timeout=timeout)
            rc: int | None = proc.returncode
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
            rc = None
    seconds = time.monotonic() - t0
    cases = []
    for line in out.splitlines():
        if line.startswith("CASE "):
            r = json.loads(line[5:])
            cases.append((r["name"], Outcome(r["kind"], r["seconds"], wrong=r["wrong"],
                                             error=r["error"])))
    if rc is None:
        cases.append(("(child)", Outcome("hang", seconds, error="no exit within the budget")))
    elif rc < 0:
        cases.append(("(child)", Outcome("crash", seconds, error=f"killed by signal {-rc}")))
    elif rc != 0:
        last = (err.strip().splitlines() or [f"exit code {rc}"])[-1]
        cases.append(("(child)", Outcome("bare", seconds, error=last[:300])))
    return cases


# -- statistics -------------------------------------------------------------------------------
_STATISTICS = """
    from fricenv_agents import statistics as S
    nan = float("nan")
    finite = lambda iv: [f"a finite answer {iv} from NaN scores"] if np.isfinite(
        np.asarray(getattr(iv, "lo", iv), dtype=float)).all() else []
    case("iqm of NaN", lambda: S.iqm([1.0, 2.0, 3.0, nan]), "NaN", finite)
    case("iqm_ci of NaN", lambda: S.iqm_ci([[1.0, 2.0, nan, 4.0]], n_boot=200), "NaN", finite)
    case("paired_ci of NaN", lambda: S.paired_ci(
        lambda a, b: a.mean(axis=(-2, -1)) - b.mean(axis=(-2, -1)),
        [np.ones((1, 4)), np.array([[1.0, nan, 2.0, 3.0]])], n_boot=200), "NaN", finite)
    labels = np.array([0.0, 0.0, 1.0, nan, 1.0, 1.0])
    seen = []
    def twice():
        for _ in range(2):
            seen.append(S.iqm_ci(np.arange(6.0), strata=labels, n_boot=200, seed=1))
        return seen
    case("NaN strata", twice, "strata",
         lambda r: ["two answers to one seeded call"] if r[0] != r[1] else
         ["an interval from NaN strata labels"])
    x = np.arange(8.0).reshape(2, 4)
    case("axis out of range", lambda: S.iqm(x, axis=5), "axis")
    case("string confidence", lambda: S.iqm_ci(x, confidence="0.9", n_boot=10), "confidence")
    case("empty tau_grid", lambda: S.tau_grid([]), "cell")
    case("n_boot 1e9", lambda: S.iqm_ci(x, n_boot=10**9), "n_boot")  # (last: 37 GiB)
"""


def statistics_class(pythonpath: str | None, budget: float) -> list[tuple[str, Outcome]]:
    return run_cases(_STATISTICS, pythonpath, budget * 6)


# -- settings ---------------------------------------------------------------------------------
_SETTINGS = """
    import fricenv
    from fricenv.regimes import Regime
    PERIODIC = (Regime.PERIODIC_STICK_SLIP, Regime.PERIODIC_OSCILLATION)
    def silent_off(m):
        if (m.q == 0).all() or not np.isin(m.labels, PERIODIC).any():
            return ["the periodicity test was switched off without a word"]
        return []
    fricenv.regime_map("coulomb", [2.0], [1.0], progress=False)  # (kernels warm)
    case("n_strobe=8", lambda: fricenv.regime_map("coulomb", [2.0, 20.0], [1.0, 2.0],
                                                  n_strobe=8, progress=False),
         "n_strobe=8", silent_off)
    case("m_max=6", lambda: fricenv.regime_map("coulomb", [2.0, 20.0], [1.0, 2.0], m_max=6,
                                               progress=False), "m_max=6", silent_off)
"""


def settings_class(pythonpath: str | None, budget: float) -> list[tuple[str, Outcome]]:
    return run_cases(_SETTINGS, pythonpath, 600.0)


# -- stored data ------------------------------------------------------------------------------
_STORED = """
    import shutil, threading
    from pathlib import Path
    import fricenv, xarray as xr
    from fricenv import mapfile
    tmp = Path(sys.argv[1])
    axes = {"u0": np.geomspace(0.2, 40.0, 4), "nu": np.array([0.25, 0.5, 1.0, 1.3, 2.0])}
    ref = tmp / "ref.zarr"
    fricenv.atlas("coulomb", axes, path=ref, chunks=(2, 2), progress=False)
    other = tmp / "other.zarr"
    fricenv.atlas("coulomb", {"u0": axes["u0"] * 1.5, "nu": axes["nu"]}, path=other,
                  chunks=(2, 2), progress=False)
    good = xr.open_zarr(ref, consolidated=False).load()
    def damaged(name, edit):
        path = tmp / f"{name}.zarr"
        shutil.copytree(ref, path)
        edit(path)
        def call():
            return fricenv.open_atlas(path).load()
        def check(ds):
            same = all(np.array_equal(ds[k].values, good[k].values, equal_nan=True)
                       for k in good.data_vars)
            return [] if same else ["a misplaced chunk read as this atlas's cells"]
        case(name, call, str(path), check)
    def swap(a, b):
        da, db = a.read_bytes(), b.read_bytes()
        a.write_bytes(db); b.write_bytes(da)
    damaged("chunks swapped", lambda p: swap(p / "label/c/0/1", p / "label/c/1/0"))
    damaged("variables swapped", lambda p: swap(p / "v_min/c/0/0", p / "v_max/c/0/0"))
    damaged("chunk from another atlas",  # (u0 is 1.5 times as large there: other speeds)
            lambda p: shutil.copy(other / "v_max/c/1/1", p / "v_max/c/1/1"))
    m = fricenv.regime_map("coulomb", [0.5, 3.0], [0.5, 1.3], progress=False)
    saved = m.save(tmp / "m.npz")
    with np.load(saved) as z:
        arrays = {k: z[k] for k in z.files}
    i, j = (int(k) for k in np.argwhere(m.done)[-1])
    arrays["labels"][i, j] = 7 if arrays["labels"][i, j] != 7 else 4
    np.savez(tmp / "relabelled.npz", **arrays)
    case("label against its statistics", lambda: fricenv.RegimeMap.load(tmp / "relabelled.npz"),
         "labels", lambda r: ["a label contradicting its statistics loaded"])
    (tmp / "data").mkdir()
    target, link = tmp / "data" / "t.npz", tmp / "link.npz"
    link.symlink_to(target)
    def through_link():
        m.save(link)
        return link
    case("save through a symlink", through_link, "",
         lambda p: [] if p.is_symlink() else ["the symlink became a regular file"])
    held, release = threading.Event(), threading.Event()
    def hold():
        with mapfile.writer_lock(target):
            held.set()
            release.wait(60)
    t = threading.Thread(target=hold); t.start(); held.wait(60)
    case("second writer through a symlink", lambda: m.save(link), "being written",
         lambda r: ["a second writer through a symlink was accepted"])
    release.set(); t.join()
"""


def stored_class(pythonpath: str | None, budget: float) -> list[tuple[str, Outcome]]:
    return run_cases(_STORED, pythonpath, 600.0)


# -- the numba cache --------------------------------------------------------------------------
_TOY_INIT = "from pathlib import Path\nfrom fricenv._numba_cache import install\n" \
            "install(Path(__file__).parent)\n"
_TOY_LEAF = "from numba import njit\n@njit(cache=True)\ndef value():\n    return 1\n"
_TOY_USER = ("from numba import njit\nfrom toypkg.leaf import value\n@njit(cache=True)\n"
             "def twice():\n    return 2 * value()\n")
_TOY_RUN = ("import warnings; warnings.simplefilter('always')\n"
            "from toypkg.user import twice\nprint('result', twice())\n")


def _toy(folder: Path) -> None:
    pkg = folder / "toypkg"
    pkg.mkdir(parents=True)
    for name, text in (("__init__", _TOY_INIT), ("leaf", _TOY_LEAF), ("user", _TOY_USER)):
        (pkg / f"{name}.py").write_text(text)


def _toy_outcome(folder: Path, pythonpath: str | None, budget: float, expect_note: str,
                 prefix: tuple = (), **extra: str) -> Outcome:
    """Run the toy kernel; sound: result 2 and, if ``expect_note``, one line saying so."""
    env = {**os.environ, "NUMBA_CACHE_DIR": "", "XDG_CACHE_HOME": str(folder / "xdg"),
           **extra}
    env["PYTHONPATH"] = os.pathsep.join([str(folder), pythonpath or
                                         str(Path(__file__).parents[1])])
    t0 = time.monotonic()
    try:
        run = subprocess.run([*prefix, sys.executable, "-c", _TOY_RUN], capture_output=True,
                             text=True, env=env, cwd=folder, timeout=budget * 6)
    except subprocess.TimeoutExpired:
        return Outcome("hang", time.monotonic() - t0)
    seconds = time.monotonic() - t0
    if run.returncode < 0:
        return Outcome("crash", seconds, error=f"killed by signal {-run.returncode}")
    if run.returncode != 0:
        return Outcome("bare", seconds, error=(run.stderr.strip().splitlines() or [""])[-1])
    if run.stdout.split() != ["result", "2"]:
        return Outcome("returned", seconds, wrong=[f"printed {run.stdout.strip()!r}"])
    said = [x for x in run.stderr.splitlines() if expect_note and expect_note in x]
    if expect_note and len(said) != 1:
        return Outcome("returned", seconds, wrong=[f"{len(said)} lines saying {expect_note!r}"])
    return Outcome("returned", seconds)


def _flip(f: Path) -> None:
    b = bytearray(f.read_bytes())
    b[len(b) // 2] ^= 0x10
    f.write_bytes(bytes(b))


_CACHE_DAMAGE = {
    "empty index": ("nbi", lambda f: f.write_bytes(b"")),
    "garbled index": ("nbi", lambda f: f.write_bytes(b"\x80\x04garbage")),
    "index of text": ("nbi", lambda f: f.write_bytes(f.read_bytes()[:20] + b"\xff" * 40)),
    "flipped data": ("nbc", _flip),
    "empty data": ("nbc", lambda f: f.write_bytes(b"")),
}


def cache_class(pythonpath: str | None, budget: float) -> list[tuple[str, Outcome]]:
    out = []
    for name, (kind, damage) in _CACHE_DAMAGE.items():
        with tempfile.TemporaryDirectory() as tmpdir:
            folder = Path(tmpdir)
            _toy(folder)
            first = _toy_outcome(folder, pythonpath, budget, "")
            if not first.ok:
                out.append((name, first))
                continue
            files = list((folder / "xdg").rglob(f"user.twice-*.{kind}"))
            if not files:  # (a tree whose cache lives elsewhere: its in-tree folder)
                files = list(folder.rglob(f"user.twice-*.{kind}"))
            for f in files:
                damage(f)
            out.append((name, _toy_outcome(folder, pythonpath, budget, "damaged")))
    prefix: tuple = ()
    if os.geteuid() == 0:
        setpriv = shutil.which("setpriv")
        if setpriv is None:
            return out
        prefix = (setpriv, "--bounding-set=-all", "--inh-caps=-all")
    with tempfile.TemporaryDirectory() as tmpdir:
        folder = Path(tmpdir)
        _toy(folder)
        (folder / "home").mkdir()
        (folder / "empty").mkdir()
        warmed = _toy_outcome(folder, pythonpath, budget, "")
        for p in [folder, *folder.rglob("*")]:
            p.chmod(p.stat().st_mode & ~0o222)
        try:
            if warmed.ok:
                out.append(("warm, read-only", _toy_outcome(
                    folder, pythonpath, budget, "", prefix, HOME=str(folder / "home"))))
            out.append(("no cache, nothing writable", _toy_outcome(
                folder, pythonpath, budget, "compile in memory", prefix,
                HOME=str(folder / "home"), XDG_CACHE_HOME=str(folder / "empty"))))
        finally:
            for p in [folder, *folder.rglob("*")]:
                p.chmod(p.stat().st_mode | 0o200)
    return out


# -- stopping ---------------------------------------------------------------------------------
_DASK = """
    from distributed import Client, LocalCluster
    import fricenv
    S = fricenv.SweepSettings(window_min=4000.0)
    u0, nu = np.geomspace(0.5, 50.0, 24), np.linspace(0.3, 2.7, 24)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        fricenv.atlas("stribeck", {"u0": u0[:1], "nu": nu[:1]}, client=client, settings=S,
                      progress=False)
        print("go", flush=True)
        try:
            fricenv.atlas("stribeck", {"u0": u0, "nu": nu}, path=sys.argv[1] + "/a.zarr",
                          settings=S, chunks=72, client=client, progress=False)
            print("END finished", flush=True)
        except BaseException as e:
            print("END " + type(e).__name__, time.perf_counter(), flush=True)
"""


def _signalled(code: str, args: list[str], env: dict, cwd: Path, ready: str, after: float,
               group: bool, sig: int, bound: float = STOP_BOUND_S
               ) -> tuple[float | None, int | None, str, str, float]:
    """Start ``code``, wait for the line ``ready``, send ``sig`` ``after`` seconds later
    (to the process group with ``group``); (seconds to exit, or None after ``bound``,
    exit code, stdout, stderr, time of the signal)."""
    proc = subprocess.Popen([sys.executable, "-c", code, *args], env=env, cwd=cwd, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    assert proc.stdout is not None and proc.stderr is not None
    lines = []
    deadline = time.monotonic() + 900.0
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if line.strip() == ready:
            break
    time.sleep(after)
    if proc.poll() is not None:  # (ended before the signal: nothing to judge)
        out, err = proc.communicate()
        return None, proc.returncode, "".join(lines) + out + "\nENDED-BEFORE", err, 0.0
    sent = time.perf_counter()
    (os.killpg if group else os.kill)(proc.pid, sig)
    try:
        proc.wait(timeout=bound)
        latency: float | None = time.perf_counter() - sent
    except subprocess.TimeoutExpired:
        latency = None
        try:
            proc.wait(timeout=30.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    out, err = proc.communicate()
    return latency, proc.returncode, "".join(lines) + out, err, sent


def _cells_kept(store: Path, pythonpath: str | None, tmp: Path) -> int:
    """Cells the store holds as done, read by the tree under test (its own format); -1 if
    it cannot open the store, 0 without one."""
    if not store.exists():
        return 0
    run = subprocess.run([sys.executable, "-c", "import sys, fricenv; print(int((fricenv."
                          "open_atlas(sys.argv[1]).label.values >= 0).sum()))", str(store)],
                         capture_output=True, text=True, env=_env(pythonpath, tmp), cwd=tmp,
                         timeout=300)
    return int(run.stdout.strip()) if run.returncode == 0 else -1


def dask_probe(group: bool, pythonpath: str | None) -> Outcome:
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        latency, rc, out, err, sent = _signalled(
            _HEAD + textwrap.dedent(_DASK), [str(tmp)], _env(pythonpath, tmp), tmp, "go", 3.0,
            group, signal.SIGINT)
        kept = _cells_kept(tmp / "a.zarr", pythonpath, tmp)
    end = [x for x in out.splitlines() if x.startswith("END ")]
    raised = end[0].split()[1] if end else f"no end (exit {rc})"
    stop_s = float(end[0].split()[2]) - sent if end and len(end[0].split()) > 2 else None
    note = (f"{raised} {stop_s:.2f} s after the signal" if stop_s is not None else raised) \
        + f", {kept} cells kept"
    if latency is None and stop_s is None:
        return Outcome("hang", 30.0, error=note)
    if raised == "finished":
        return Outcome("returned", 0.0, error="finished before the signal: not judged")
    wrong = []
    if raised != "SweepInterrupted":
        wrong.append(f"raised {raised}, not SweepInterrupted")
    if stop_s is not None and stop_s > STOP_BOUND_S:
        wrong.append(f"stopped {stop_s:.1f} s after the signal")
    if kept <= 0:
        wrong.append("no cell kept")
    return Outcome("returned", stop_s or 0.0, wrong=wrong, error=note)


_TRAIN = """
    import os, sys, threading, time
    from fricenv_agents import train
    progress = sys.argv[1] + "/run/progress.csv"
    def ready():  # (a first row of progress.csv: learning runs, its kernels compiled)
        while not (os.path.exists(progress) and len(open(progress).readlines()) >= 2):
            time.sleep(0.05)
        print("go", flush=True)
    threading.Thread(target=ready, daemon=True).start()
    train.main(["--algo", "ppo", "--scene", "paper", "-n", "100000", "--eval-freq", "0",
                "--eval-episodes", "1", "--no-progress", "--run-dir", sys.argv[1] + "/run",
                "-params", "n_envs:2", "n_steps:16", "batch_size:32"])
"""


def train_probe(pythonpath: str | None) -> Outcome:
    """SIGTERM 1 s into learning (as ``timeout``, SLURM or ``docker stop`` send it): sound
    if the process exits within 30 s (saving takes a few) with the model saved and its
    config saying the run was interrupted."""
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        latency, rc, out, err, _ = _signalled(textwrap.dedent(_TRAIN), [str(tmp)],
                                              _env(pythonpath, tmp), tmp, "go", 1.0, False,
                                              signal.SIGTERM, bound=30.0)
        run = tmp / "run"
        saved = (run / "model.zip").exists()
        config = (run / "config.yml").read_text() if (run / "config.yml").exists() else ""
    if latency is None:
        return Outcome("hang", 30.0, error="no exit within 30 s of SIGTERM")
    wrong = [] if saved else ["no model.zip after SIGTERM"]
    if "interrupted: true" not in config:
        wrong.append("config.yml does not say the run was interrupted")
    return Outcome("returned", latency, wrong=wrong, error=f"exit {rc} in {latency:.2f} s")


def stops_class(pythonpath: str | None, budget: float) -> list[tuple[str, Outcome]]:
    out = [("Dask Ctrl-C to the client", dask_probe(False, pythonpath)),
           ("Dask Ctrl-C in a terminal", dask_probe(True, pythonpath))]
    out.append(("SIGTERM to train", train_probe(pythonpath)))
    for n in ("-2", "0"):
        out += run_cases(f"""
            case("--local-workers {n}", lambda: cli("atlas", "--axis", "u0=1,2",
                 "--local-workers", "{n}", "--out", sys.argv[1] + "/a.zarr"),
                 "--local-workers", lambda code: ["ran with --local-workers {n}"])
        """, pythonpath, budget * 3)
    return out


# -- smaller ----------------------------------------------------------------------------------
_SMALLER = """
    from dataclasses import replace
    from pathlib import Path
    import fricenv
    from fricenv.envs.stick_slip import StickSlipEnv
    tmp = Path(sys.argv[1])
    env = StickSlipEnv(scene="viscous", obs_noise={"x": 0.05}, obs_delay=2)
    env.reset(seed=0)
    state = env.get_state()
    delay = state.delay.copy(); delay[-1, 2] = np.nan
    accepted = lambda r: ["accepted"]
    case("set_state NaN delay line", lambda: env.set_state(replace(state, delay=delay)),
         "delay", accepted)
    gen, rows = state.noise
    rows = np.vstack([rows, np.zeros((1, 9))])
    rows[0, 0] = np.nan
    case("set_state NaN noise", lambda: env.set_state(replace(state, noise=(gen, rows))),
         "normals", accepted)
    import importlib
    W = importlib.import_module("fricenv.warmup")  # (fricenv.warmup is the function)
    W.run_part = lambda *a: 0.0  # (nothing compiles: the arguments are judged)
    case("warmup(parallel='no')", lambda: W.warmup(workloads=["sweep"], parallel="no"),
         "parallel", accepted)
    case("warmup(laws='coulomb')", lambda: W.warmup(laws="coulomb", workloads=["sweep"]),
         "laws", lambda r: [] if list(r) == ["sweep:coulomb"] else [f"ran {list(r)}"])
    (tmp / "file").write_text("x")
    case("simulate --out under a file",
         lambda: cli("simulate", "--t-end", "50", "--out", str(tmp / "file" / "run")),
         "is a file", accepted)
    case("repeated --axis", lambda: cli("atlas", "--axis", "u0=1,2", "--axis", "u0=3",
                                        "--out", str(tmp / "a.zarr")), "'u0'", accepted)
    from fricenv_agents.runs import load_controller
    src = Path(fricenv.__file__).parents[1] / "agents" / "pretrained"
    import shutil
    for suffix in (".zip", "_vecnormalize.pkl", ".yml"):
        shutil.copy(src / f"ppo_paper{suffix}", tmp / f"ppo_paper{suffix}")
    model, norm = tmp / "ppo_paper.zip", tmp / "ppo_paper_vecnormalize.pkl"
    good_model, good_norm = model.read_bytes(), norm.read_bytes()
    flipped = bytearray(good_model)
    for k in range(len(flipped) // 3, len(flipped) // 3 + 64):  # (inside a member's data)
        flipped[k] ^= 0x5A
    model.write_bytes(bytes(flipped))
    case("damaged model file", lambda: load_controller(model), "ppo_paper.zip", accepted)
    model.write_bytes(good_model)
    norm.write_bytes(good_norm[:len(good_norm) // 2])
    case("damaged normalisation file", lambda: load_controller(model),
         "ppo_paper_vecnormalize.pkl", accepted)
"""

#: Commands that run well past the signal (Stribeck cells: tens of seconds on 2 cores).
_CTRL_C = {
    "map": ["map", "--law", "stribeck", "--u0", "geom:0.5:50:150", "--nu", "lin:0.1:3:150",
            "--no-progress"],
    "atlas": ["atlas", "--law", "stribeck", "--axis", "u0=geom:0.5:50:150", "--axis",
              "nu=lin:0.1:3:150", "--no-progress"],
    "reproduce": ["reproduce", "--quick", "--no-progress"],
}


def ctrl_c_probe(command: list[str], pythonpath: str | None) -> Outcome:
    """Ctrl-C 3 s after the command's first line: sound if it exits 130 without a
    traceback (as ``fricenv train`` does)."""
    code = ("import signal, sys\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "print('go', flush=True)\nfrom fricenv.cli import main\nsys.exit(main())\n")
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        latency, rc, out, err, _ = _signalled(code, [*command, "--out", str(tmp / "out")],
                                              _env(pythonpath, tmp), tmp, "go", 3.0, False,
                                              signal.SIGINT)
    if out.endswith("ENDED-BEFORE"):
        return Outcome("returned", 0.0, error=f"exit {rc} before the signal: not judged")
    if latency is None:
        return Outcome("hang", 30.0, error="no exit within 2 s of Ctrl-C")
    if rc == 130 and "Traceback" not in err:
        return Outcome("returned", latency, error=f"exit 130 in {latency:.2f} s")
    return Outcome("bare", latency, error=f"exit {rc}, "
                   + ("a traceback" if "Traceback" in err else "no traceback"))


def smaller_class(pythonpath: str | None, budget: float) -> list[tuple[str, Outcome]]:
    out = run_cases(_SMALLER, pythonpath, 600.0)
    out += [(f"Ctrl-C on {name}", ctrl_c_probe(argv, pythonpath))
            for name, argv in _CTRL_C.items()]
    return out


#: The edge classes, in the order they run, and their probes.
EDGE_CLASSES = {"statistics": statistics_class, "settings": settings_class,
                "stored": stored_class, "cache": cache_class, "stops": stops_class,
                "smaller": smaller_class}
