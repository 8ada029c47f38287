"""What ``import fricenv`` and the command line's help load: no numba, no torch.

Each check runs in a fresh interpreter, since this process has long imported both.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import fricenv
from fricenv.cli import COMMANDS, PLUGIN_SUMMARIES

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "torch", "stable_baselines3", "scipy", "dask", "xarray", "zarr")


def _fresh(code: str) -> Any:
    """Run ``code`` in a new interpreter from the checkout; it prints a JSON object."""
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


_REPORT = ("import json, sys; print(json.dumps({'heavy': [m for m in HEAVY if m in "
           "sys.modules], 'fricenv': sorted(m for m in sys.modules "
           "if m.split('.')[0] == 'fricenv')}))").replace("HEAVY", repr(HEAVY))


def test_import_fricenv_loads_no_numba() -> None:
    """The package, the environments' ids and the compile notice (standard library only),
    nothing of the kernels."""
    got = _fresh("import fricenv; " + _REPORT)
    assert got == {"heavy": [], "fricenv": [
        "fricenv", "fricenv._compile_listener", "fricenv._numba_cache", "fricenv._tbb",
        "fricenv._version", "fricenv.compile_notice", "fricenv.envs", "fricenv.envs.ids"]}


def test_import_fricenv_is_quick() -> None:
    """A bound that only proves the import does no compile-sized work (about 0.2 s warm
    on 2 cores; far more only under heavy load)."""
    got = _fresh("import time; t = time.perf_counter(); import fricenv; "
                 "import json; print(json.dumps({'s': time.perf_counter() - t}))")
    assert got["s"] < 3.0


def _help_report(argv: list[str]) -> Any:
    """The heavy modules ``fricenv <argv>`` loaded, and whether it printed a usage."""
    return _fresh("import contextlib, io, json, sys\nfrom fricenv.cli import main\n"
                  "with contextlib.redirect_stdout(out := io.StringIO()):\n"
                  f"    try: main({argv!r})\n"
                  "    except SystemExit: pass\n"
                  f"print(json.dumps({{'heavy': [m for m in {HEAVY!r} if m in sys.modules], "
                  "'usage': out.getvalue().startswith('usage: fricenv')}))")


@pytest.mark.parametrize("command", ["", *COMMANDS, *PLUGIN_SUMMARIES])
def test_help_loads_neither_numba_nor_torch(command: str) -> None:
    """The built-in commands and the agents' (``train``, ``evaluate``: their parsers and
    argument checks import the kernels, torch and SB3 only after parsing)."""
    got = _help_report([command, "--help"] if command else ["--help"])
    assert got == {"heavy": [], "usage": True}


def test_make_loads_the_kernels_registration_does_not() -> None:
    got = _fresh("import gymnasium as gym, fricenv, sys\n"
                 "before = 'numba' in sys.modules\n"
                 "env = gym.make('fricenv/StickSlip-v0')\n"
                 "import json; print(json.dumps({'before': before, "
                 "'after': 'numba' in sys.modules, 'steps': env.spec.max_episode_steps}))")
    assert got == {"before": False, "after": True, "steps": 200}


def test_make_is_quick() -> None:
    """``gymnasium.make`` checks the episode's cost in numpy and calls no kernel, so a warm
    make is about 0.3 s on 2 cores (the first kernel call, about 0.35 s of numba's setup,
    comes with the first reset). The bound proves only that make loads or compiles no
    kernel. The first process fills numba's cache, the second one is timed."""
    code = ("import time, gymnasium as gym, fricenv\n"
            "t = time.perf_counter(); gym.make('fricenv/StickSlip-v0')\n"
            "import json; print(json.dumps({'s': time.perf_counter() - t}))")
    _fresh(code)
    assert _fresh(code)["s"] < 3.0


def test_public_names_resolve_and_are_listed() -> None:
    """``from fricenv import X`` for every name of ``__all__``; ``dir()`` lists them."""
    for name in fricenv.__all__:
        assert getattr(fricenv, name) is not None, name
    assert set(fricenv.__all__) <= set(dir(fricenv))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        fricenv.nope  # noqa: B018


def test_importing_a_module_keeps_the_function_of_its_name() -> None:
    """``import fricenv.simulate`` (or ``fricenv.warmup``) first must not turn
    ``fricenv.simulate`` into the module."""
    got = _fresh("import fricenv, fricenv.simulate, fricenv.warmup, json; "
                 "print(json.dumps([callable(fricenv.simulate), callable(fricenv.warmup), "
                 "fricenv.simulate.__module__, fricenv.warmup.__module__]))")
    assert got == [True, True, "fricenv.simulate", "fricenv.warmup"]


def test_horizons_are_the_scenes() -> None:
    """The ids are registered from ``HORIZONS``; the scenes take theirs from it too."""
    from fricenv.envs import ENV_IDS, HORIZONS
    from fricenv.envs.scenes import SCENES

    assert set(HORIZONS) == set(SCENES) == set(ENV_IDS.values())
    assert all(SCENES[s].max_episode_steps == n for s, n in HORIZONS.items())


def test_the_package_pickles_by_name() -> None:
    """Dask and multiprocessing pickle functions that name the package (the package module
    is a ModuleType subclass, which pickle would not know how to reduce otherwise)."""
    import pickle

    assert pickle.loads(pickle.dumps(fricenv)) is fricenv


def test_a_users_own_parallel_kernel_gets_tbb_after_import_fricenv() -> None:
    """``import fricenv`` loads TBB (not numba) where numba's default layer order finds it
    first, so a parallel kernel of the user's, run before any of fricenv's, is thread-safe
    and fork-safe too (the README install puts libtbb where the loader does not look)."""
    got = _fresh("import numba, numpy as np, fricenv, json\n"
                 "@numba.njit(parallel=True)\n"
                 "def f(a):\n"
                 "    for i in numba.prange(a.size): a[i] = i\n"
                 "f(np.zeros(4)); print(json.dumps({'layer': numba.threading_layer()}))")
    assert got["layer"] == "tbb"


def test_the_main_job_needs_no_torch(tmp_path: Path) -> None:
    """README's command 1 installs fricenv without the ``rl`` extra: the reproduction and
    every module it imports run with torch and stable-baselines3 unimportable."""
    readme = (ROOT / "README.md").read_text()
    assert "pip install -e . && fricenv reproduce --quick" in readme
    code = ("import sys, json\n"
            "sys.modules['torch'] = None; sys.modules['stable_baselines3'] = None\n"
            "import importlib, pkgutil, fricenv.reproduce as R\n"
            "for m in pkgutil.iter_modules(R.__path__):\n"
            "    importlib.import_module(f'fricenv.reproduce.{m.name}')\n"
            f"R.main(['--quick', '--only', '2', '--quiet', '--out', {str(tmp_path)!r}])\n"
            "print(json.dumps(sorted(p.name for p in __import__('pathlib').Path("
            f"{str(tmp_path)!r}).iterdir())))")
    assert _fresh(code) == ["fig2_friction_laws.png", "report.md"]
