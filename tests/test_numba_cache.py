"""The numba cache follows edits across a package's modules (fricenv._numba_cache)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

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
    # the in-tree cache (cachepkg/__pycache__), whatever the caller's NUMBA_CACHE_DIR
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "GUARD": "1" if guard else "0",
           "NUMBA_CACHE_DIR": ""}

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

