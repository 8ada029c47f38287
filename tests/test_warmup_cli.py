"""``fricenv warmup`` and the compile notice: parts in worker processes, the cache check
that compiles nothing, and one line on stderr before a command compiles."""

from __future__ import annotations

import json
import logging
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from clirun import run

import fricenv
from fricenv import _numba_cache, compile_notice
from fricenv.cli import _notice
from fricenv.warmup import Part, parts

ROOT = Path(fricenv.__file__).resolve().parent.parent
NOTICE = "compiling numba kernels"
#: How long a stand-in part waits for the other worker to start its part (generous: two
#: spawned interpreters each import fricenv on a busy machine).
RENDEZVOUS_SECONDS = 120.0


def python(code: str, cache: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """``code`` (or ``-m`` with ``args``) in a fresh interpreter running this tree's
    fricenv with ``cache`` as its numba cache."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(cache)}
    argv = [sys.executable, *args] if not code else [sys.executable, "-c", code]
    return subprocess.run(argv, capture_output=True, text=True, env=env, cwd=cache.parent,
                          check=True, timeout=600)


def rendezvous_part(part: Part, parallel: bool) -> float:
    """A stand-in for ``run_part``: leaves this process's id and waits until another
    process has left its own, which only happens if two parts run at once."""
    folder = Path(os.environ["FRICENV_TEST_RENDEZVOUS"])
    (folder / f"{part.name.replace(':', '_')}.{os.getpid()}").touch()
    deadline = time.monotonic() + RENDEZVOUS_SECONDS
    while len(list(folder.iterdir())) < 2:
        if time.monotonic() > deadline:
            raise TimeoutError("the other part never started")
        time.sleep(0.05)
    return 0.25


@pytest.mark.parametrize(("argv", "named"), [
    (["--laws", "coulomb", "frictionless"], ["--laws", "'frictionless'"]),
    (["--workloads", "simulation"], ["--workloads", "'simulation'"]),
    (["--scenes", "moon"], ["--scenes", "'moon'"]),
    (["--jobs", "0"], ["--jobs", "'0'"]),
    (["--jobs", "two"], ["--jobs", "'two'"]),
])
def test_bad_arguments_are_usage_errors_naming_the_value(capsys, argv, named):
    code, out, err = run(capsys, "warmup", *argv)
    assert code == 2
    for text in named:
        assert text in err
    assert out == ""


def test_parts_are_one_per_law_and_workload_and_per_scene():
    assert [p.name for p in parts(["coulomb", "stribeck"], ["sweep", "simulate", "env"],
                                  ["paper"])] == [
        "simulate:coulomb", "sweep:coulomb", "simulate:stribeck", "sweep:stribeck",
        "env:paper"]
    with pytest.raises(ValueError, match="'moon'"):
        parts(scenes=["moon"])


def test_a_single_name_is_one_name_and_parallel_must_be_a_bool(monkeypatch):
    """``laws='coulomb'`` ran the letters as law names; ``parallel='no'`` ran in parallel."""
    assert parts("stribeck", "sweep") == parts(["stribeck"], ["sweep"])
    assert [p.name for p in parts("coulomb", "env", "paper")] == ["env:paper"]
    with pytest.raises(TypeError, match=r"laws must be a name or an iterable of names, got 5"):
        parts(laws=5)  # type: ignore[arg-type]
    import importlib

    module = importlib.import_module("fricenv.warmup")  # (fricenv.warmup is the function)
    ran = []
    monkeypatch.setattr(module, "run_part", lambda *a: ran.append(a) or 0.0)
    for flag in ("no", 0, None):
        with pytest.raises(TypeError, match=r"parallel must be a bool \(True or False\)"):
            module.warmup(parallel=flag)  # type: ignore[arg-type]
    assert ran == []
    assert module.warmup(laws="coulomb", workloads="sweep") == {"sweep:coulomb": 0.0}


def test_print_digest_is_the_cache_stamp(capsys):
    code, out, _ = run(capsys, "warmup", "--print-digest")
    assert code == 0
    assert out.strip() == _numba_cache.source_digest(Path(fricenv.__file__).parent)
    assert re.fullmatch(r"[0-9a-f]{64}", out.strip())


def test_jobs_run_parts_in_separate_processes_and_report_each(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr(sys.modules["fricenv.warmup"], "run_part", rendezvous_part)
    monkeypatch.setenv("FRICENV_TEST_RENDEZVOUS", str(tmp_path))
    code, out, _ = run(capsys, "warmup", "--workloads", "simulate", "--laws", "coulomb",
                       "stribeck", "--jobs", "2")
    assert code == 0
    pids = {int(f.suffix[1:]) for f in tmp_path.iterdir()}
    assert len(pids) == 2 and os.getpid() not in pids
    assert {f.stem for f in tmp_path.iterdir()} == {"simulate_coulomb", "simulate_stribeck"}
    for name in ("simulate:coulomb", "simulate:stribeck"):
        assert re.search(rf"^{name}\s+0\.2\s", out, re.MULTILINE), out
    assert re.search(r"^total\s+0\.5\b", out, re.MULTILINE), out


def test_quiet_prints_nothing(capsys, monkeypatch):
    ran = []
    monkeypatch.setattr(sys.modules["fricenv.warmup"], "run_part",
                        lambda part, parallel: ran.append(part.name) or 0.0)
    monkeypatch.setattr(compile_notice, "is_cached", lambda workload, method: False)
    code, out, err = run(capsys, "warmup", "--workloads", "sweep", "--quiet")
    assert (code, out, err) == (0, "", "")
    assert ran == ["sweep:coulomb"]
    code, out, err = run(capsys, "warmup", "--workloads", "sweep")
    assert err.count(NOTICE) == 1 and "sweep (exact)" in err
    assert "sweep:coulomb" in out


def test_every_entry_kernel_resolves_to_a_cached_dispatcher():
    """The one mapping of workloads to entry kernels still names real kernels."""
    for workload, methods in compile_notice.ENTRY_KERNELS.items():
        assert workload in compile_notice.COMPILE_SECONDS
        for names in methods.values():
            for name in names:
                kernel = compile_notice.resolve(name)
                assert kernel._cache._cache_file is not None, name


def test_the_cache_check_reads_the_index_only(tmp_path):
    """Cold in an empty cache, cached once the kernel ran there (the cheap RK4 kernel),
    and the check itself compiles nothing."""
    cache = tmp_path / "cache"
    check = ("from fricenv import compile_notice as c, core\n"
             "print(c.is_cached('simulate', 'rk4'), len(core.run_rk4.overloads))")
    assert python(check, cache).stdout.split() == ["False", "0"]
    python("import fricenv\n"
           "fricenv.simulate(fricenv.OscillatorParams(), 1.0, method='rk4', dt_out=0.5)",
           cache)
    assert python(check, cache).stdout.split() == ["True", "0"]


def test_the_cache_check_follows_numbas_index(monkeypatch):
    """The index numba returns decides (``{}`` for another source stamp or version)."""
    kernel = compile_notice.resolve(compile_notice.ENTRY_KERNELS["sweep"]["event"][0])
    monkeypatch.setattr(kernel, "overloads", {})  # (as if not compiled in this process)
    cache_file = kernel._cache._cache_file
    monkeypatch.setattr(cache_file, "_load_index", lambda: {})
    assert not compile_notice.is_cached("sweep", "event")
    here = kernel._cache._index_key(None, kernel.targetctx.codegen())
    monkeypatch.setattr(cache_file, "_load_index", lambda: {("sig", *here[1:]): "x.nbc"})
    assert compile_notice.is_cached("sweep", "event")
    other = ("sig", ("another machine",), here[2])
    monkeypatch.setattr(cache_file, "_load_index", lambda: {other: "x.nbc"})
    assert not compile_notice.is_cached("sweep", "event")


@pytest.mark.slow
def test_a_warmup_fills_the_cache_its_check_reads(tmp_path):
    cache = tmp_path / "cache"
    check = ("from fricenv.warmup import Part, is_cached\n"
             "print(is_cached(Part('simulate', 'coulomb')))")
    assert python(check, cache).stdout.split() == ["False"]
    done = python("", cache, "-m", "fricenv.cli", "warmup", "--workloads", "simulate")
    assert done.stderr.count(NOTICE) == 1
    assert re.search(r"^simulate:coulomb\s+\d+\.\d\s+compiled$", done.stdout, re.MULTILINE)
    assert python(check, cache).stdout.split() == ["True"]


def test_the_command_says_once_that_it_compiles_and_nothing_when_warm(tmp_path):
    cache = tmp_path / "cache"
    argv = ["-m", "fricenv.cli", "simulate", "--method", "rk4", "--t-end", "1",
            "--out", str(tmp_path / "out")]
    cold = python("", cache, *argv).stderr
    assert cold.count(NOTICE) == 1, cold
    line = next(line for line in cold.splitlines() if NOTICE in line)
    assert line.startswith("fricenv: ") and "simulate (rk4)" in line
    assert str(cache) in line and "about 5 s" in line
    warm = python("", cache, *argv).stderr
    assert NOTICE not in warm, warm


def test_commands_with_parsers_of_their_own_are_announced(monkeypatch, caplog):
    cold: set[tuple[str, str]] = set()
    monkeypatch.setattr(compile_notice, "is_cached", lambda w, m: (w, m) not in cold)
    caplog.set_level(logging.INFO, logger="fricenv")
    argv = ["--algo", "ppo", "--scene", "stribeck"]
    assert not _notice.announce_command("train", argv)
    cold.add(("vector_env", "event"))
    assert _notice.announce_command("train", argv)
    assert not _notice.announce_command("train", [*argv, "--help"])
    assert not _notice.announce_command("train", ["--scene", "moon"])  # its parser says why
    cold.add(("sweep", "exact"))
    assert _notice.announce_command("reproduce", ["--only", "2"])
    cold.clear()
    assert not _notice.announce_command("reproduce", [])
    assert [r.getMessage().count(NOTICE) for r in caplog.records] == [1, 1]
    assert "vector_env (event)" in caplog.records[0].getMessage()


#: A cold call from Python, timed from the call's start to the first line on stderr.
API_CALL = """
import json, sys, time
import fricenv

class Tap:
    def __init__(self, stream):
        self.stream, self.first = stream, None
    def write(self, text):
        if self.first is None and text.strip():
            self.first = time.monotonic() - t0
        return self.stream.write(text)
    def flush(self):
        self.stream.flush()

sys.stderr = Tap(sys.stderr)
p = fricenv.OscillatorParams(nu=0.1, u0=1.15)
t0 = time.monotonic()
fricenv.simulate(p, 1.0, method="rk4")
print(json.dumps({"first": sys.stderr.first, "call": time.monotonic() - t0}))
"""


def test_a_python_call_says_once_that_it_compiles(tmp_path):
    """From an empty cache, a call from Python prints one line to stderr within 2 s of its
    start; FRICENV_QUIET=1 silences it; with the kernels cached there is none. (RK4: the
    cheapest kernels to compile.)"""
    cache = tmp_path / "cache"
    cold = python(API_CALL, cache)
    assert cold.stderr.count(NOTICE) == 1, cold.stderr
    line = cold.stderr.strip()
    assert line.startswith("fricenv: compiling numba kernels for simulate: about ")
    assert str(cache) in line and "FRICENV_QUIET=1" in line and "fricenv warmup" in line
    timing = json.loads(cold.stdout)
    assert timing["first"] is not None and timing["first"] < 2.0, timing
    warm = python(API_CALL, cache)
    assert warm.stderr == "" and json.loads(warm.stdout)["first"] is None
    quiet = subprocess.run(
        [sys.executable, "-c", API_CALL], capture_output=True, text=True, check=True,
        timeout=600, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT),
                                        "NUMBA_CACHE_DIR": str(tmp_path / "other"),
                                        "FRICENV_QUIET": "1"})
    assert quiet.stderr == "", quiet.stderr


def test_configured_logging_decides_where_the_notice_goes(tmp_path):
    """Without logging configured the notice is printed; with it, it is a record of the
    ``fricenv`` logger that the application's handlers and levels judge."""
    cache = tmp_path / "cache"
    code = ("import logging, fricenv\n"
            "from fricenv import compile_notice\n"
            "print(compile_notice.announce([('simulate', 'rk4')]))\n"
            "logging.basicConfig(level=logging.INFO, format='%(name)s %(message)s')\n"
            "compile_notice.announce([('simulate', 'rk4')])\n"
            "logging.getLogger('fricenv').setLevel(logging.WARNING)\n"
            "compile_notice.announce([('simulate', 'rk4')])\n")
    out = python(code, cache)
    assert out.stdout.split() == ["True"]
    lines = out.stderr.splitlines()
    assert len(lines) == 2 and all(NOTICE in line for line in lines), lines
    assert lines[0].startswith("fricenv: ") and lines[1].startswith("fricenv.compile_notice ")


def test_each_workload_and_method_is_announced_once(monkeypatch):
    """A workload's helpers and its first method's entry kernel make one line; a second
    method's entry kernel one more; a shared kernel or a helper of an announced workload
    none; inside a command, only entry kernels the command did not name."""
    said: list[str] = []
    monkeypatch.setattr(compile_notice, "_announced", set())
    monkeypatch.setattr(compile_notice, "emit", said.append)
    monkeypatch.setattr(compile_notice, "cache_location", lambda: "CACHE")
    entries: dict[str, tuple[str | None, str | None]] = {
        "helper": (None, None), "record_exact": ("simulate", "exact"),
        "cell_exact": ("sweep", "exact"), "cell_event": ("sweep", "event"),
        "start_episode": ("env", None), "step_event": ("env", "event")}
    monkeypatch.setattr(compile_notice, "entry_of", lambda d: entries[d.name])
    monkeypatch.setattr(compile_notice, "_api_module", lambda: "fricenv.simulate")

    class Kernel:
        def __init__(self, name: str) -> None:
            self.name = name
            self.py_func = self  # (named by its module when no workload matches)
            self.__module__ = "fricenv.somewhere"

    for name in ("helper", "record_exact", "helper", "cell_exact", "cell_event",
                 "cell_event", "start_episode", "step_event"):
        compile_notice.compile_starting(Kernel(name))
    assert [line.split(":")[0] for line in said] == [
        "compiling numba kernels for simulate", "compiling numba kernels for sweep (exact)",
        "compiling numba kernels for sweep (event)", "compiling numba kernels for env"]
    assert "about 20 s" in said[0] and "CACHE" in said[0] and "FRICENV_QUIET=1" in said[0]
    said.clear()
    # (the command's own notice, ``announce``, marks its pairs as announced)
    compile_notice._announced.update({"vector_env", "vector_env (event)"})
    with compile_notice.in_command():
        compile_notice.compile_starting(Kernel("helper"))
        entries["step_batch"] = ("vector_env", "event")
        compile_notice.compile_starting(Kernel("step_batch"))
        entries["step_exact"] = ("env", "exact")
        compile_notice.compile_starting(Kernel("step_exact"))
    assert [line.split(":")[0] for line in said] == [
        "compiling numba kernels for env (exact)"]
