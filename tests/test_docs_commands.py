"""The documented ``fricenv train`` -> ``fricenv evaluate`` commands reproduce the published
table, and a run's ``config.yml`` records a command line that runs.

The commands are read from docs/agents.md and run as written through the ``fricenv``
command, in subprocesses, with a tiny training budget appended (the trained row is not
compared, only the baselines', which do not depend on the training). The best-constant
search is not rerun: its cache, keyed on the scene and the evaluation's env kwargs, is
copied from docs/results into the output folder, so that an evaluation on other episodes
than the published ones would miss it and find another constant.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("stable_baselines3", reason="the agents need the rl extra")

from fricenv_agents import train as T  # noqa: E402
from fricenv_agents.layout import PRETRAINED  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
#: Appended to the documented training: a few hundred steps on 4 plants.
TINY = ["-n", "256", "--eval-freq", "0", "--eval-episodes", "1", "--quiet",
        "-params", "n_envs:4", "n_steps:32", "batch_size:64", "n_epochs:1"]


def documented(command: str) -> list[str]:
    """The words of the ``fricenv <command>`` line in docs/agents.md's first block."""
    text = (ROOT / "docs" / "agents.md").read_text()
    block = text.split("## Training and evaluating", 1)[1].split("```bash\n", 1)[1]
    block = block.split("```", 1)[0]
    [line] = [line for line in block.splitlines() if line.startswith(f"fricenv {command} ")]
    return shlex.split(line)


def fricenv(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, "-m", "fricenv.cli", *argv], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr
    return res


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """The documented training, tiny, run where a user would: its default folder under
    ``out/`` of the working folder."""
    work = tmp_path_factory.mktemp("work")
    argv = documented("train")
    assert argv[:2] == ["fricenv", "train"] and "--hyperparams" not in argv
    fricenv(*argv[1:], *TINY, cwd=work)
    [run] = (work / "out" / "runs").glob("ppo_self_excited_s0_*")
    return run


def test_the_documented_evaluation_reproduces_the_published_baselines(trained):
    work = trained.parents[2]
    argv = documented("evaluate")
    out = work / Path(argv[argv.index("--out") + 1])
    assert out.relative_to(work).parts[0] == "out"
    out.mkdir(parents=True)
    for name in ("best_constant_self_excited.json", "regime_map_self_excited.npz"):
        shutil.copy(RESULTS / name, out / name)
    runs = argv.index("--runs") + 1
    argv[runs:runs + 1] = [str(trained.relative_to(work))]  # (the shell's glob)
    fricenv(*argv[1:], "--no-plots", "--quiet", cwd=work)
    assert yaml.safe_load((trained / "config.yml").read_text())["env_kwargs"] == {
        "max_episode_steps": 100}  # it trained on short episodes ...
    md = (out / "self_excited.md").read_text()
    assert "episodes of 400 control steps" in md  # ... and is scored on the scene's
    assert "Environment settings changed" not in md
    got = json.loads((out / "self_excited_results.json").read_text())["controllers"]
    published = json.loads((RESULTS / "self_excited_results.json").read_text())["controllers"]
    for name in ("zero", "random", "best_constant", "feedback"):
        for metric in ("stick_fraction", "ret"):
            assert got[name][metric]["mean"] == pytest.approx(
                published[name][metric]["mean"], rel=1e-9), (name, metric)
    assert "zero excitation | 50 | 0.3865 ± 0.0008" in md
    assert "best constant (u0 = 0.60, nu = 1.25)" in md


def test_max_steps_scores_other_episodes(trained, tmp_path):
    out = tmp_path / "eval"
    fricenv("evaluate", "--runs", str(trained), "--controllers", "zero", "--seeds", "1",
            "--episodes", "2", "--max-steps", "100", "--no-plots", "--quiet",
            "--out", str(out), cwd=tmp_path)
    md = (out / "self_excited.md").read_text()
    assert "episodes of 100 control steps" in md and "'max_episode_steps': 100" in md


def test_config_records_a_command_line_that_runs(trained):
    """The recorded command is the one that ran (``fricenv train ...``, not ``... train
    train ...``): it parses, and it runs as far as its help."""
    command = yaml.safe_load((trained / "config.yml").read_text())["command"]
    words = shlex.split(command)
    assert words[:2] == ["fricenv", "train"] and "train" not in words[2:], command
    assert words[2:] == documented("train")[2:] + TINY
    T.build_parser().parse_args(words[2:])
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"
           f"{os.environ.get('PATH', '')}"}
    res = subprocess.run([*words, "--help"], capture_output=True, text=True, env=env,
                         timeout=300)
    assert res.returncode == 0 and res.stdout.startswith("usage: fricenv train"), res.stderr


def test_the_command_line_names_how_the_run_was_started():
    assert T.command_line(["--algo", "ppo", "--run-dir", "a b"], "fricenv train") == (
        "fricenv train --algo ppo --run-dir 'a b'")
    assert T.command_line(["--algo", "sac"], None) == (
        "python -m fricenv_agents.train --algo sac")


def shipped_configs() -> list[Path]:
    return sorted([*PRETRAINED.glob("*.yml"), *PRETRAINED.glob("benchmark/*/config.yml"),
                   *PRETRAINED.glob("short/*/config.yml")])


@pytest.mark.parametrize("config", shipped_configs(), ids=lambda p: p.parent.name
                         if p.name == "config.yml" else p.name)
def test_the_shipped_configs_record_command_lines_that_parse(config):
    command = yaml.safe_load(config.read_text())["command"]
    words = shlex.split(command)
    assert words[:3] == ["python", "-m", "fricenv_agents.train"], command
    args = T.build_parser().parse_args(words[3:])
    assert re.fullmatch(r"(ppo|sac)", args.algo)


def test_a_shipped_config_command_runs_with_help():
    command = yaml.safe_load((PRETRAINED / "ppo_self_excited.yml").read_text())["command"]
    words = shlex.split(command)
    words[0] = sys.executable
    res = subprocess.run([*words, "--help"], capture_output=True, text=True, timeout=300,
                         cwd=ROOT)
    assert res.returncode == 0 and "usage:" in res.stdout, res.stderr


# -- the shipped models by name ---------------------------------------------------------------
def test_shipped_models_are_named_in_help_and_found_by_name(capsys, tmp_path, monkeypatch):
    """``pretrained:<scene>`` finds the model inside the installed package, from any working
    folder; a wrong name is a usage error that lists the shipped ones."""
    from fricenv_agents import evaluate as E
    from fricenv_agents.layout import model_path, pretrained_names

    assert pretrained_names() == ["paper", "self_excited", "stribeck", "viscous"]
    help_text = " ".join(E.build_parser("fricenv evaluate").format_help().split())
    for name in pretrained_names():
        assert f"pretrained:{name}" in help_text
        assert model_path(f"pretrained:{name}").is_file()
    monkeypatch.chdir(tmp_path)
    [table] = E.main(["--models", "pretrained:self_excited", "--controllers", "zero",
                      "--seeds", "1", "--episodes", "2", "--no-plots", "--quiet"])
    assert table == Path("out/eval/self_excited.md")
    assert "PPO (ppo_self_excited.zip)" in table.read_text()
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        E.main(["--models", "pretrained:moon"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "no pretrained model 'moon'" in err and "pretrained:self_excited" in err


def test_the_shipped_models_are_package_data():
    """A wheel carries every file ``pretrained:<name>`` needs (the model, its observation
    statistics and its config), by the package-data globs of pyproject.toml."""
    import fnmatch
    import tomllib

    from fricenv_agents.layout import pretrained_names

    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["fricenv_agents"]
    for name in pretrained_names():
        for suffix in (".zip", "_vecnormalize.pkl", ".yml"):
            path = f"pretrained/ppo_{name}{suffix}"
            assert (PRETRAINED.parent / path).is_file(), path
            assert any(fnmatch.fnmatch(path, g) for g in globs), path


def test_the_agents_commands_write_under_out_by_default():
    from fricenv_agents import benchmark as BM
    from fricenv_agents import evaluate as E

    assert T.build_parser().parse_args(["--algo", "ppo", "--scene", "paper"]).log_folder == (
        Path("out/runs"))
    assert E.build_parser().parse_args([]).out == Path("out/eval")
    assert BM.build_parser().parse_args([]).out == Path("out/control-benchmark")
    assert "fricenv_agents/hyperparams" in " ".join(T.build_parser().format_help().split())
