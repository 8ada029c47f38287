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
from fricenv.envs import steppers

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
    for kernel in (core.advance, steppers.ANY.step_batch, steppers.ANY.step_batch_parallel):
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


# -- damaged or read-only caches ------------------------------------------------------------
_CHECKED_RUN = ("import warnings; warnings.simplefilter('always'); " + _RUN)


def _toy_package(tmp_path: Path) -> Path:
    """The two-kernel package of the tests above, with the guard installed."""
    pkg = tmp_path / "cachepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(_INIT)
    (pkg / "user.py").write_text(_USER)
    (pkg / "leaf.py").write_text(_LEAF.format(value=1))
    return pkg


def _toy_run(tmp_path: Path, prefix: tuple[str, ...] = (), **env: str
             ) -> tuple[str, str, str]:
    """(result, cache hit, stderr) of the toy package's kernel in a fresh interpreter."""
    root = Path(fricenv.__file__).parent.parent
    run_env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{root}",
               "GUARD": "1", "NUMBA_CACHE_DIR": "", "XDG_CACHE_HOME": str(tmp_path / "xdg"),
               **env}
    out = subprocess.run([*prefix, sys.executable, "-c", _CHECKED_RUN], capture_output=True,
                         text=True, env=run_env, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    result, cache_hit = out.stdout.split()
    return result, cache_hit, out.stderr


def _flip_middle(data: bytes) -> bytes:
    b = bytearray(data)
    b[len(b) // 2] ^= 0x10
    return bytes(b)


def _cut_with_a_seal(file: Path) -> None:
    """A data file cut short, then sealed again: the seal matches, pickle must refuse."""
    payload = _numba_cache.unseal(file.name, file.read_bytes())
    file.write_bytes(_numba_cache.seal(file.name, payload[:len(payload) // 2]))


def _unsealed(file: Path) -> None:
    """The file as numba alone writes it: sound bytes, but nothing vouches for them."""
    file.write_bytes(_numba_cache.unseal(file.name, file.read_bytes()))


def _from_another_name(file: Path) -> None:
    """Another file's sealed bytes put in this one's place (sealed with its own name)."""
    other = file.with_name(file.name.replace("user.twice", "leaf.value"))
    if not other.exists():
        other = next(p for p in file.parent.glob(f"*{file.suffix}") if p != file)
    file.write_bytes(other.read_bytes())


#: (file kind, how it is damaged): every way the probe broke the cache, and more.
DAMAGE = {
    "empty index": ("nbi", lambda f: f.write_bytes(b"")),  # EOFError before
    "garbled index": ("nbi", lambda f: f.write_bytes(b"\x80\x04garbage")),  # Unpickling
    "flipped index": ("nbi", lambda f: f.write_bytes(_flip_middle(f.read_bytes()))),
    "index of text": ("nbi", lambda f: f.write_bytes(f.read_bytes()[:20] + b"\xff" * 40)),
    "unsealed index": ("nbi", _unsealed),
    "flipped data": ("nbc", lambda f: f.write_bytes(_flip_middle(f.read_bytes()))),
    "empty data": ("nbc", lambda f: f.write_bytes(b"")),
    "cut data": ("nbc", _cut_with_a_seal),
    "unsealed data": ("nbc", _unsealed),
    "moved data": ("nbc", _from_another_name),
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_a_damaged_cache_file_is_a_cache_miss_named_once(tmp_path, damage):
    """A zero-length index raised EOFError, other damage UnpicklingError,
    UnicodeDecodeError or LLVM errors, from every call until the folder was deleted; a
    flipped bit in a data file crashed the process. Now: the right result, one line
    naming the folder, and the next process loads the repaired cache."""
    _toy_package(tmp_path)
    assert _toy_run(tmp_path)[:2] == ("2", "False")  # compiled and cached
    folder = next((tmp_path / "xdg" / "cachepkg" / "numba").iterdir())
    kind, damage_it = DAMAGE[damage]
    (file,) = folder.glob(f"user.twice-*.{kind}")
    damage_it(file)
    result, hit, err = _toy_run(tmp_path)
    assert (result, hit) == ("2", "False")
    lines = [line for line in err.splitlines() if "NumbaCacheWarning" in line]
    assert len(lines) == 1, err
    assert f"numba's cache in {folder} is damaged" in lines[0]
    assert "Traceback" not in err
    assert _toy_run(tmp_path) == ("2", "True", "")  # repaired: loaded, nothing said


def _unprivileged() -> tuple[str, ...]:
    """A prefix that runs a command without the power to write where its mode says no:
    as root, ``setpriv`` dropping every capability (CAP_DAC_OVERRIDE let root write into a
    folder of mode 555); otherwise nothing."""
    if os.geteuid() != 0:
        return ()
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: no way to make a folder unwritable")
    return (setpriv, "--bounding-set=-all", "--inh-caps=-all")


def _read_only(*folders: Path) -> None:
    for folder in folders:
        for p in [folder, *folder.rglob("*")]:
            p.chmod(p.stat().st_mode & ~0o222)


def test_a_warm_read_only_cache_is_used_and_none_compiles_in_memory(tmp_path):
    """Where neither the per-user folder nor the package's own could be written, the first
    call raised ``RuntimeError: cannot cache function ... no locator available``, even
    with a warm cache there (an image's, another user's)."""
    prefix = _unprivileged()
    pkg = _toy_package(tmp_path)
    home = tmp_path / "home"
    home.mkdir()
    assert _toy_run(tmp_path)[:2] == ("2", "False")  # warmed, with the right to write
    empty = tmp_path / "empty-xdg"
    empty.mkdir()
    _read_only(tmp_path / "xdg", pkg, home, empty)
    probe = subprocess.run([*prefix, sys.executable, "-c",
                            f"open({str(tmp_path / 'xdg' / 'probe')!r}, 'w')"],
                           capture_output=True, text=True)
    assert probe.returncode != 0 and "Permission denied" in probe.stderr  # (the case holds)
    before = sorted(p for p in tmp_path.rglob("*"))
    # warm and read-only: loaded as it is, silently
    assert _toy_run(tmp_path, prefix, HOME=str(home)) == ("2", "True", "")
    # nothing cached, nothing writable: compiled in memory, said once
    result, hit, err = _toy_run(tmp_path, prefix, HOME=str(home), XDG_CACHE_HOME=str(empty))
    assert (result, hit) == ("2", "False")
    lines = [line for line in err.splitlines() if "NumbaCacheWarning" in line]
    assert len(lines) == 1 and "no writable numba cache" in lines[0], err
    assert sorted(p for p in tmp_path.rglob("*")) == before  # nothing written anywhere


def test_an_unsealed_index_of_another_source_is_a_silent_miss(tmp_path):
    """An index that an older fricenv left in a shared folder (``NUMBA_CACHE_DIR``, or
    ``__pycache__``) has no seal, but is stale, not damaged: nothing is said about it."""
    import pickle

    _toy_package(tmp_path)
    assert _toy_run(tmp_path)[:2] == ("2", "False")
    folder = next((tmp_path / "xdg" / "cachepkg" / "numba").iterdir())
    (index,) = folder.glob("user.twice-*.nbi")
    index.write_bytes(pickle.dumps(numba.__version__) + pickle.dumps(("another source", {})))
    assert _toy_run(tmp_path) == ("2", "False", "")
    assert _toy_run(tmp_path) == ("2", "True", "")
