"""The ``fricenv.commands`` plugin point, and the packaging that registers the agents there."""

from __future__ import annotations

import importlib
import subprocess
import sys
import tomllib
import types
from importlib import metadata
from pathlib import Path

import pytest
from clirun import run

from fricenv import cli

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


@pytest.fixture(autouse=True)
def _fresh_plugins():
    """``cli.plugins`` caches what it found; each test sees its own entry points."""
    cli.plugins.cache_clear()
    yield
    cli.plugins.cache_clear()


def _entry_points(monkeypatch, *eps: metadata.EntryPoint) -> None:
    """Make ``fricenv`` see exactly ``eps`` in its group (and nothing else anywhere)."""
    def fake(**params):
        assert params == {"group": cli.PLUGIN_GROUP}
        return metadata.EntryPoints(eps)

    monkeypatch.setattr(metadata, "entry_points", fake)


def _ep(name: str, value: str, dist: object | None = None) -> metadata.EntryPoint:
    ep = metadata.EntryPoint(name, value, cli.PLUGIN_GROUP)
    return ep if dist is None else ep._for(dist)


@pytest.fixture
def hello_module(monkeypatch):
    """A plugin module whose ``main`` records its call and returns exit status 3."""
    mod = types.ModuleType("fricenv_test_hello")
    calls: list[tuple[list[str], str]] = []

    def main(argv, prog):
        calls.append((list(argv), prog))
        print("hello from the plugin")
        return 3

    mod.main = main  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    return calls


def test_a_plugin_is_listed_and_runs(monkeypatch, capsys, hello_module):
    _entry_points(monkeypatch, _ep("hello", "fricenv_test_hello:main"))
    code, out, _ = run(capsys, "--help")
    assert code == 0
    assert "hello" in out
    code, out, _ = run(capsys, "hello", "--flag", "x")
    assert code == 3
    assert "hello from the plugin" in out
    assert hello_module == [(["--flag", "x"], "fricenv hello")]


def test_missing_agents_say_how_to_get_them(monkeypatch, capsys):
    _entry_points(monkeypatch)
    code, out, _ = run(capsys, "--help")
    assert code == 0
    assert "train" in out and "evaluate" in out
    assert "[not installed]" in out
    assert 'pip install "fricenv[rl]"' in out
    code, _, err = run(capsys, "train", "--algo", "ppo")
    assert code == 2
    assert "fricenv train is not installed" in err
    assert 'pip install -e ".[rl]"' in err


class _Dist:
    """A distribution whose ``rl`` extra needs a package nobody has installed."""

    name = "fricenv-test-dist"
    requires = ["numpy>=1.26", 'fricenv-no-such-package>=1; extra == "rl"',
                'pytest>=8; extra == "dev"']


def test_a_plugin_without_its_extra_refuses_to_run(monkeypatch, capsys, hello_module):
    ep = _ep("hello", "fricenv_test_hello:main [rl]", _Dist())
    assert cli.missing_requirements(ep) == ["fricenv-no-such-package"]
    _entry_points(monkeypatch, ep)
    code, out, _ = run(capsys, "--help")
    assert "[needs fricenv-no-such-package]" in out
    code, _, err = run(capsys, "hello")
    assert code == 2
    assert "fricenv hello needs fricenv-no-such-package" in err
    assert hello_module == []  # never imported, never called


def test_a_plugin_cannot_take_a_builtin_name(monkeypatch, capsys, hello_module):
    _entry_points(monkeypatch, _ep("simulate", "fricenv_test_hello:main"))
    assert cli.plugins() == {}
    code, out, _ = run(capsys, "simulate", "--help")
    assert code == 0
    assert "usage: fricenv simulate" in out
    assert hello_module == []


def test_help_imports_no_plugin_and_no_torch():
    code = ("import sys\n"
            "from fricenv.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = ('torch', 'stable_baselines3', 'fricenv_agents')\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert res.stdout.strip().splitlines()[-1] == "[]"


def test_pyproject_registers_the_agents_commands():
    eps = PYPROJECT["project"]["entry-points"][cli.PLUGIN_GROUP]
    assert set(eps) == set(cli.PLUGIN_SUMMARIES)
    for name, value in eps.items():
        target, _, extras = value.partition(" ")
        assert extras == "[rl]"
        module, _, func = target.partition(":")
        assert callable(getattr(importlib.import_module(module), func)), name


def test_pyproject_installs_every_package_under_its_name():
    """Every package folder is listed (package-dir cannot rename what ``packages.find``
    finds, so the list is explicit), and ``agents/`` installs as ``fricenv_agents``."""
    tool = PYPROJECT["tool"]["setuptools"]
    assert tool["package-dir"] == {"fricenv_agents": "agents"}
    folders = {p.parent.relative_to(ROOT).as_posix().replace("/", ".")
               for p in (ROOT / "fricenv").rglob("__init__.py")}
    assert set(tool["packages"]) == folders | {"fricenv_agents"}
    assert "agents" not in tool["packages"]
    assert set(PYPROJECT["tool"]["setuptools"]["package-data"]) == {"fricenv",
                                                                   "fricenv_agents"}
