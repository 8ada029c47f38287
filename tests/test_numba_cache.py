"""The numba cache follows edits across a package's modules (fricenv._numba_cache)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numba
import pytest

import fricenv
from fricenv import _numba_cache, core
from fricenv.envs import batch

_INIT = """\
import os
from pathlib import Path
if os.environ.get("GUARD") == "1":
    from fricenv._numba_cache import install
    install(Path(__file__).parent)
"""
_LEAF = """\
from numba import njit
@njit(cache=True)
def value():
    return {value}
"""
_USER = """\
from numba import njit
from cachepkg.leaf import value
@njit(cache=True)
def twice():
    return 2 * value()
"""
_RUN = "from cachepkg.user import twice; print(twice(), twice.stats.cache_hits[()] > 0)"


def test_fricenv_kernels_are_keyed_on_the_whole_package():
    root = Path(fricenv.__file__).parent
    assert _numba_cache.installed_for(root)
    digest = _numba_cache.source_digest(root)
    for kernel in (core.advance, batch.step_batch, batch.step_batch_parallel):
        assert kernel._cache._impl.locator.get_source_stamp() == digest


@pytest.mark.parametrize("guard", [True, False])
def test_an_edit_of_an_inlined_module_recompiles_its_callers(tmp_path, guard):
    """Without the guard, numba keeps the caller compiled against the old leaf (the stale
    result this test shows, numba issue #1833); with it, the edit is seen."""
    pkg = tmp_path / "cachepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(_INIT)
    (pkg / "user.py").write_text(_USER)
    # the per-user cache (with the guard) or the in-tree one (without), whatever the
    # caller's NUMBA_CACHE_DIR
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "GUARD": "1" if guard else "0",
           "NUMBA_CACHE_DIR": "", "XDG_CACHE_HOME": str(tmp_path / "xdg")}

    def run() -> tuple[str, str]:
        out = subprocess.run([sys.executable, "-c", _RUN], capture_output=True, text=True,
                             env=env, cwd=tmp_path, check=True)
        result, cache_hit = out.stdout.split()
        return result, cache_hit

    (pkg / "leaf.py").write_text(_LEAF.format(value=1))
    assert run() == ("2", "False")  # compiled and cached
    assert run() == ("2", "True")  # loaded from the cache
    (pkg / "leaf.py").write_text(_LEAF.format(value=5))
    assert run() == (("10", "False") if guard else ("2", "True"))



_COPY_RUN = """\
import json
from numba.core import event
compiles = event.RecordingListener()
event.register("numba:compile", compiles)
import fricenv
from fricenv import compile_notice, core
fricenv.simulate(fricenv.OscillatorParams.preset("coulomb", u0=1.0, nu=0.5), 1.0,
                 method="rk4", dt_out=0.5)
print(json.dumps({"file": fricenv.__file__, "where": compile_notice.cache_location(),
                  "kernel_dir": core.run_rk4._cache.cache_path,
                  "compiles": sum(1 for _, e in compiles.buffer if e.is_start)}))
"""


def _copy_package(to: Path) -> Path:
    shutil.copytree(Path(fricenv.__file__).parent, to / "fricenv",
                    ignore=shutil.ignore_patterns("__pycache__"))
    return to


def _run_copy(copy: Path, **env: str) -> dict:
    run_env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    run_env.update(PYTHONPATH=str(copy), **env)
    out = subprocess.run([sys.executable, "-c", _COPY_RUN], capture_output=True, text=True,
                         env=run_env, cwd=copy, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_second_copy_of_the_package_loads_what_the_first_compiled(tmp_path):
    """Two installs of the same source (a new venv, a reinstall, another checkout) share
    the per-user cache: nothing in its paths or keys depends on where the package lives."""
    xdg = tmp_path / "xdg"
    first = _run_copy(_copy_package(tmp_path / "a"), XDG_CACHE_HOME=str(xdg))
    second = _run_copy(_copy_package(tmp_path / "b"), XDG_CACHE_HOME=str(xdg))
    assert first["file"] != second["file"]
    assert first["compiles"] > 0
    assert second["compiles"] == 0, second
    digest = _numba_cache.source_digest(Path(fricenv.__file__).parent)
    folder = xdg / "fricenv" / "numba" / f"{numba.__version__}-{digest}"
    assert first["where"] == second["where"] == str(folder)
    assert first["kernel_dir"] == second["kernel_dir"] == str(folder / "core")


def test_numba_cache_dir_still_decides_where_the_cache_is(tmp_path):
    copy = _copy_package(tmp_path / "a")
    out = _run_copy(copy, XDG_CACHE_HOME=str(tmp_path / "xdg"),
                    NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    assert out["where"] == str(tmp_path / "numba")
    assert Path(out["kernel_dir"]).parent == tmp_path / "numba"
    assert out["compiles"] > 0
    assert not (tmp_path / "xdg" / "fricenv").exists()


def test_old_digest_folders_are_pruned_and_recent_ones_kept(tmp_path, monkeypatch):
    parent = tmp_path / "numba"
    now = time.time()
    ages = {"recent": 60.0, "old1": 2e4, "old2": 3e4, "old3": 4e4, "old4": 5e4}
    for name, age in ages.items():
        (parent / name).mkdir(parents=True)
        os.utime(parent / name, (now - age, now - age))
    current = parent / "current"
    current.mkdir()
    monkeypatch.setattr(_numba_cache, "KEEP_DIGESTS", 3)
    _numba_cache._prune(parent, current)
    # the two most recent others are kept (with the current one, three), and the rest is
    # older than PRUNE_AFTER_S
    assert sorted(p.name for p in parent.iterdir()) == ["current", "old1", "recent"]
