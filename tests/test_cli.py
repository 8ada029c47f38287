"""The ``fricenv`` command: dispatch, help, outputs and clear usage errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from clirun import run

import fricenv
from fricenv.cli import COMMANDS


def test_console_script_lists_every_command():
    out = subprocess.run([sys.executable, "-m", "fricenv.cli", "--help"], capture_output=True,
                         text=True, check=True).stdout
    for name in COMMANDS:
        assert name in out


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_has_help(capsys, name):
    code, out, _ = run(capsys, name, "--help")
    assert code == 0
    assert "usage:" in out


def test_unknown_command_is_a_usage_error(capsys):
    code, _, err = run(capsys, "simulte")
    assert code == 2
    assert "invalid choice: 'simulte'" in err


def test_simulate_writes_figure_and_data(capsys, tmp_path):
    code, out, _ = run(capsys, "simulate", "--case", "5a", "--t-end", "40", "--out",
                       str(tmp_path))
    assert code == 0
    assert (tmp_path / "time_history.png").stat().st_size > 0
    data = np.load(tmp_path / "trajectory.npz")
    ref = fricenv.simulate(fricenv.OscillatorParams(nu=0.1, u0=1.15), 40.0)
    np.testing.assert_array_equal(data["x"], ref.x)
    np.testing.assert_array_equal(data["event_t"], ref.event_t)
    assert "stick_fraction" in out


def test_simulate_csv(capsys, tmp_path):
    code, _, _ = run(capsys, "simulate", "--law", "stribeck", "--set", "u0=2", "--set",
                     "nu=0.5", "--t-end", "10", "--format", "csv", "--out", str(tmp_path))
    assert code == 0
    rows = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    assert rows.shape[1] == 4
    assert rows[-1, 0] == 10.0
    events = (tmp_path / "trajectory_events.csv").read_text().splitlines()
    assert events[0] == "t,kind,name,x" and len(events) > 1
    names = {"1": "stick", "2": "slip", "3": "reversal"}
    for line in events[1:]:
        t, kind, name, x = line.split(",")
        assert names[kind] == name and float(t) >= 0 and float(x) == float(x)


@pytest.mark.parametrize(("argv", "message"), [
    (["--set", "lam=-1"], "lam must be >= 0, got -1.0"),
    (["--set", "lam"], "expected NAME=VALUE, got 'lam'"),
    (["--set", "u0=abc"], "not a number: 'abc'"),
    (["--set", "mass=2"], "mass"),
    (["--t-end", "nan"], "not a finite number: 'nan'"),
    (["--case", "9z"], "invalid choice: '9z'"),
    (["--law", "coulomb", "--case", "5a"], "not allowed with argument"),
])
def test_simulate_usage_errors(capsys, tmp_path, argv, message):
    code, _, err = run(capsys, "simulate", "--out", str(tmp_path / "o"), *argv)
    assert code == 2
    assert message in err
    assert not (tmp_path / "o" / "trajectory.npz").exists()


def test_map_writes_and_resumes(capsys, tmp_path):
    argv = ["map", "--u0", "geom:0.5:50:3", "--nu", "0.1,1,2.5", "--out", str(tmp_path),
            "--no-progress"]
    code, out, _ = run(capsys, *argv)
    assert code == 0
    assert "3 x 3 cells" in out
    m = fricenv.RegimeMap.load(tmp_path / "map.npz")
    ref = fricenv.regime_map("coulomb", np.geomspace(0.5, 50, 3), [0.1, 1, 2.5],
                             progress=False)
    np.testing.assert_array_equal(m.labels, ref.labels)
    assert (tmp_path / "map.png").stat().st_size > 0
    code, _, _ = run(capsys, *argv)  # a finished map resumes with nothing to do
    assert code == 0


@pytest.mark.parametrize(("spec", "message"), [
    ("geom:0:1:3", "a geometric grid needs START, STOP > 0"),
    ("lin:0:1", "expected lin:START:STOP:N"),
    ("lin:0:1:2.5", "N must be a whole number"),
    ("lin:0:1:0", "N must be in [1, 1000000]"),
    ("a,b", "expected geom:START:STOP:N"),
])
def test_map_grid_errors(capsys, tmp_path, spec, message):
    code, _, err = run(capsys, "map", "--u0", spec, "--nu", "1", "--out", str(tmp_path))
    assert code == 2
    assert message in err


def test_map_refuses_a_file_as_folder(capsys, tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    code, _, err = run(capsys, "map", "--u0", "1", "--nu", "1", "--out", str(f))
    assert code == 2
    assert "is a file, not a folder" in err


def test_bench_names_its_scripts(capsys):
    code, out, _ = run(capsys, "bench", "--help")
    assert code == 0
    for name in ("solvers", "sweep", "env"):
        assert name in out
    code, _, err = run(capsys, "bench", "nosuch")
    assert code == 2
    assert "invalid choice: 'nosuch'" in err


def test_train_and_reproduce_keep_their_options(capsys):
    code, out, _ = run(capsys, "train", "--help")
    assert code == 0
    assert "usage: fricenv train" in out
    assert "--algo" in out
    code, out, _ = run(capsys, "reproduce", "--help")
    assert "usage: fricenv reproduce" in out
    assert "--quick" in out


def test_atlas_shares_the_plant_options(capsys, tmp_path):
    code, _, err = run(capsys, "atlas", "--set", "lam=-1", "--axis", "u0=1,2",
                       "--out", str(tmp_path / "a.zarr"))
    assert code == 2
    assert "lam must be >= 0, got -1.0" in err
    assert not (tmp_path / "a.zarr").exists()


def test_the_simulate_figure_has_one_title_per_fact(capsys, tmp_path, monkeypatch):
    """The panel names the law and parameters; the figure's title adds the method, span
    and stick fraction instead of repeating them."""
    from fricenv import plotting

    figures = []
    save = plotting.save

    def keep(fig, path, *args, **kwargs):
        figures.append(fig)
        return save(fig, path, *args, **kwargs)

    monkeypatch.setattr(plotting, "save", keep)
    code, _, _ = run(capsys, "simulate", "--method", "rk4", "--t-end", "2", "--out",
                     str(tmp_path))
    assert code == 0
    [fig] = figures
    title, panel = fig._suptitle.get_text(), fig.axes[0].get_title()
    assert "η = 0.6" in panel and "η" not in title, (title, panel)
    assert title.startswith("rk4 method, τ from 0 to 2, stick-time fraction ")


def test_the_report_shows_fig2(tmp_path):
    from fricenv.reproduce import run as reproduce

    report = reproduce(tmp_path, quick=True, progress=False, only=["2"])
    text = report.read_text()
    assert "## Fig. 2: the friction laws" in text and "(fig2_friction_laws.png)" in text
    assert (tmp_path / "fig2_friction_laws.png").is_file()


def test_simulate_refuses_an_out_folder_it_cannot_make_before_the_run(capsys, tmp_path,
                                                                      monkeypatch):
    """``--out`` under a file ran the whole simulation, then died writing it."""
    runs = []
    monkeypatch.setattr(fricenv, "simulate", lambda *a, **k: runs.append(a))
    f = tmp_path / "file"
    f.write_text("x")
    code, _, err = run(capsys, "simulate", "--out", str(f / "sub" / "run"))
    assert code == 2
    assert f"{str(f)!r} is a file, not a folder" in err
    long_name = tmp_path / ("x" * 300)  # (no file system takes a 300-byte name)
    code, _, err = run(capsys, "simulate", "--out", str(long_name))
    assert code == 2
    assert "cannot be a folder: File name too long" in err
    if Path("/proc/self").is_dir():  # a folder where even root cannot make one
        code, _, err = run(capsys, "simulate", "--out", "/proc/fricenv-out")
        assert code == 2
        assert "--out '/proc/fricenv-out' cannot be made" in err
    assert runs == [] and f.read_text() == "x"


def test_atlas_names_a_repeated_axis_and_refuses_worker_counts_below_one(capsys, tmp_path):
    store = tmp_path / "a.zarr"
    code, _, err = run(capsys, "atlas", "--axis", "u0=1,2", "--axis", "nu=1",
                       "--axis", "u0=3", "--out", str(store))
    assert code == 2
    assert "parameter 'u0' is given twice" in err
    for n in ("0", "-2", "two"):  # -2 started no worker and hung, 0 ran without Dask
        code, _, err = run(capsys, "atlas", "--axis", "u0=1,2", "--local-workers", n,
                           "--out", str(store))
        assert code == 2
        assert f"--local-workers: expected an integer >= 1, got {n!r}" in err
    assert not store.exists()


def test_an_interrupted_command_exits_130_in_one_line(capsys, tmp_path, monkeypatch):
    """Ctrl-C on map, atlas and reproduce printed a traceback with status -2 or 1."""
    import signal

    from fricenv import reproduce
    from fricenv.atlas import api
    from fricenv.calls import SweepInterrupted

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(reproduce, "run", stop)
    code, _, err = run(capsys, "reproduce", "--quick", "--out", str(tmp_path / "r"))
    assert code == 130
    assert err.splitlines()[-1] == ("fricenv reproduce: interrupted (SIGINT); finished maps "
                                    f"and cells are kept in {tmp_path / 'r'} (rerun to resume)")

    def term(*a, **k):
        raise SweepInterrupted(signum=signal.SIGTERM)

    monkeypatch.setattr(api, "atlas", term)
    code, _, err = run(capsys, "atlas", "--axis", "u0=1,2", "--out", str(tmp_path / "a"))
    assert code == 128 + signal.SIGTERM
    assert err.strip().endswith(f"fricenv atlas: interrupted (SIGTERM); finished chunks are "
                                f"in {tmp_path / 'a'} (rerun to resume)")
    monkeypatch.setattr(fricenv, "simulate", stop)  # (simulate has no handler of its own)
    code, _, err = run(capsys, "simulate", "--out", str(tmp_path / "s"))
    assert (code, err.splitlines()[-1]) == (130, "fricenv simulate: interrupted (SIGINT)")
    assert "Traceback" not in err


def test_an_interrupt_swallowed_by_a_c_callback_is_delivered_again(capsys):
    """Ctrl-C while numba compiled could land in llvmlite's ctypes callback, where Python
    prints "Exception ignored" and carries on: the command then ran to its end."""
    import ctypes

    from fricenv.interrupts import interrupts_redelivered

    @ctypes.CFUNCTYPE(ctypes.c_int)
    def callback() -> int:
        raise KeyboardInterrupt

    after = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts_redelivered():
            callback()  # (the exception cannot cross the C frame)
            after.append("the block went on")
    assert after == ["the block went on"]  # and then raised before it ended
    assert "Exception ignored" not in capsys.readouterr().err

    def other() -> int:
        raise ValueError("not an interrupt")

    seen = []
    previous = sys.unraisablehook
    sys.unraisablehook = seen.append
    try:
        with interrupts_redelivered():
            ctypes.CFUNCTYPE(ctypes.c_int)(other)()
    finally:
        sys.unraisablehook = previous
    assert [type(u.exc_value) for u in seen] == [ValueError]  # left to the hook in place


@pytest.mark.parametrize("command", [
    ["map", "--u0", "geom:0.5:50:40", "--nu", "lin:0.1:3:40", "--no-progress"],
    ["atlas", "--axis", "u0=geom:0.5:50:40", "--axis", "nu=lin:0.1:3:40", "--no-progress"],
    ["reproduce", "--quick", "--no-progress"],
])
def test_ctrl_c_on_a_real_command_exits_130_without_a_traceback(tmp_path, command):
    """SIGINT once the command has announced its work (while it imports, compiles or
    computes, wherever it lands): status 130 and no traceback."""
    import os
    import signal
    import time

    out = tmp_path / ("a.zarr" if command[0] == "atlas" else "out")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-c", "import signal, sys; "
                             "signal.signal(signal.SIGINT, signal.default_int_handler); "
                             "from fricenv.cli import main; sys.exit(main())",
                             *command, "--out", str(out)],
                            stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stderr is not None
    first = proc.stderr.readline()  # the stage line (or the compile notice)
    assert first, "the command printed nothing"
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    t0 = time.monotonic()
    rest = proc.stderr.read()
    code = proc.wait(timeout=60)
    assert code == 130, first + rest
    assert "Traceback" not in rest, rest
    assert "interrupted (SIGINT)" in rest
    assert time.monotonic() - t0 < 30
