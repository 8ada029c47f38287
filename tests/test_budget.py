"""Every public call returns or raises within its step budget, and Ctrl-C stops it.

The runs that used to hang (slip far stiffer than the model's scale, a start far from it)
go in a subprocess with a timeout, so that a regression fails the test instead of hanging
the suite; each child times its call after a warm-up call of the same kernels (so numba
compilation is not counted) and prints the seconds taken.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from fricenv import (
    MAX_STEPS_PER_CALL,
    MAX_STEPS_PER_TAU,
    OscillatorParams,
    SimulationError,
    cell_statistics,
    run_stats,
    simulate,
)
from fricenv.layout import ST_N_STEPS, STATUS_STEP_BUDGET
from fricenv.regimes import Regime

ROOT = Path(__file__).resolve().parents[1]
#: Longest a call over budget may take to raise (seconds, on a busy machine).
RAISE_S = 10.0
#: Longest Ctrl-C may take to end a running call.
INTERRUPT_S = 1.0
#: Time allowed a child process, numba compilation from a cold cache included.
CHILD_TIMEOUT_S = 600.0
#: A run over budget without stiff parameters: a start at x0 = 1e12 (~3e7 steps in a unit
#: of tau), and the call that makes it.
FAR = "OscillatorParams.preset('stribeck', u0=5.0, nu=1.0)"
FAR_STATE = "OscillatorState.start(p, x0=1e12)"


def _child(code: str) -> str:
    """Run ``code`` in a fresh interpreter (the repository on its path); its stdout."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=CHILD_TIMEOUT_S, env=env, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def _seconds(out: str, tag: str) -> float:
    for line in out.splitlines():
        if line.startswith(tag + " "):
            return float(line.split()[1])
    raise AssertionError(f"no {tag!r} line in {out!r}")


def test_budget_defaults_are_exported() -> None:
    assert MAX_STEPS_PER_TAU == 1e6 and MAX_STEPS_PER_CALL == 1e7


@pytest.mark.parametrize("call", [run_stats, simulate])
def test_a_low_budget_raises_with_its_status(call) -> None:
    p = OscillatorParams.preset("stribeck")
    with pytest.raises(SimulationError, match="max_steps_per_tau") as e:
        call(p, 10.0, max_steps=25)  # the scan's own 20 steps pass; the run needs more
    assert e.value.status == STATUS_STEP_BUDGET
    with pytest.raises(ValueError, match="raise max_steps"):  # the scan alone is over it
        call(p, 10.0, max_steps=5)
    with pytest.raises(SimulationError) as e:
        call(p, 10.0, max_steps_per_tau=3)
    assert e.value.status == STATUS_STEP_BUDGET
    call(p, 10.0, max_steps_per_tau=1e4, max_steps=1e4)  # enough: it runs


def test_rk4_steps_over_budget_are_refused_before_the_run() -> None:
    p = OscillatorParams.preset("coulomb")
    with pytest.raises(SimulationError, match="RK4 steps") as e:
        simulate(p, 10.0, method="rk4", dt=0.04, max_steps_per_tau=10)
    assert e.value.status == STATUS_STEP_BUDGET


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "1e6"])
def test_budget_values_are_checked(bad) -> None:
    p = OscillatorParams.preset("coulomb")
    with pytest.raises((ValueError, TypeError), match="max_steps"):
        run_stats(p, 1.0, max_steps=bad)
    with pytest.raises((ValueError, TypeError), match="max_steps_per_tau"):
        simulate(p, 1.0, max_steps_per_tau=bad)


def test_a_budget_that_is_not_reached_changes_nothing() -> None:
    p = OscillatorParams.preset("stribeck", u0=1.15, eta=0.6, nu=0.1)
    a = run_stats(p, 50.0)
    b = run_stats(p, 50.0, max_steps_per_tau=1e4, max_steps=1e5)
    assert a == b
    ta = simulate(p, 50.0)
    tb = simulate(p, 50.0, max_steps_per_tau=1e4)
    assert np.array_equal(ta.x, tb.x) and np.array_equal(ta.v, tb.v)


@pytest.mark.parametrize(("b1", "b3"), [(-1e6, 0.0), (-1e10, 0.0), (-1e12, 0.0),
                                        (-1e8, 1e12)])
def test_stiff_slip_is_refused_before_it_runs(b1: float, b3: float) -> None:
    """b1 = -1e10 .. -1e12 gave stick fractions 0.18-0.24 with status OK where a Radau
    integration gives 0.19158, or ran out of budget, or blamed chattering. Slip damped
    faster than SLIP_STIFFNESS_LIMIT is refused, naming the parameters and the limit."""
    from fricenv.params import SLIP_STIFFNESS_LIMIT

    p = OscillatorParams(b1=b1, b3=b3, u0=5.0, nu=1.0)
    for call in (run_stats, simulate):
        with pytest.raises(ValueError, match=rf"too stiff .*b1': {b1!r}.*"
                                             rf"SLIP_STIFFNESS_LIMIT = {SLIP_STIFFNESS_LIMIT:g}"):
            call(p, 3.8)
    with pytest.raises(ValueError, match="too stiff"):
        cell_statistics([p])
    ok = OscillatorParams(b1=-0.9e5, u0=5.0, nu=1.0)  # within the limit: it runs
    assert run_stats(ok, 3.0).stick_fraction >= 0.0


def test_a_run_over_budget_raises_within_seconds() -> None:
    """A start at x0 = 1e12 takes ~3e7 steps in a unit of tau: the budget ends it."""
    out = _child(f"""
import time
from fricenv import OscillatorParams, OscillatorState, SimulationError, run_stats, simulate
p = {FAR}
for name, call in (("run_stats", run_stats), ("simulate", simulate)):
    call(p, 1.0)  # warm-up: same kernels
    t = time.perf_counter()
    try:
        call(p, 3.8, state={FAR_STATE}, max_steps=2e6)
    except SimulationError as e:
        assert e.status == {STATUS_STEP_BUDGET}, e
        print(name, time.perf_counter() - t)
""")
    assert _seconds(out, "run_stats") <= RAISE_S
    assert _seconds(out, "simulate") <= RAISE_S


def test_env_refuses_stiff_slip_at_reset() -> None:
    import gymnasium as gym

    env = gym.make("fricenv/StickSlipSelfExcited-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="too stiff"):
        env.reset(seed=0, options={"b1": -1e8})


@pytest.mark.parametrize("options", [
    {"b1": 1e12, "b3": 1e12},
    {"x0": 1e12, "b1": 0.2, "b3": 0.16},
])
def test_env_steps_over_budget_raise_within_seconds(options: dict) -> None:
    """Stiff anti-damped slip, or a start at x0 = 1e12 (~3e7 steps in a unit of tau), took
    10-38 s per env.step."""
    env_id = ("fricenv/StickSlipSelfExcited-v0" if "x0" not in options
              else "fricenv/StickSlip-v0")
    out = _child(f"""
import time
import gymnasium as gym
import numpy as np
import fricenv
env = gym.make({env_id!r})
env.reset(seed=0)
a = np.zeros(env.action_space.shape, np.float32)
env.step(a)  # warm-up
env.reset(seed=0, options={options!r})
worst = 0.0
for _ in range(3):
    t = time.perf_counter()
    try:
        env.step(a)
    except RuntimeError as e:
        assert "budget" in str(e), e
        worst = max(worst, time.perf_counter() - t)
        break
    worst = max(worst, time.perf_counter() - t)
print("step", worst)
""")
    assert _seconds(out, "step") <= RAISE_S


def test_a_sweep_cell_over_budget_is_unresolved_with_its_status() -> None:
    p = OscillatorParams.preset("stribeck", u0=1.15, eta=0.6, nu=0.1)
    labels, _, _, status = cell_statistics([p], x0=1e12, transient_min=1.0, window_min=1.0)
    assert status[0] == STATUS_STEP_BUDGET
    assert labels[0] == Regime.UNRESOLVED


def test_a_cell_of_many_calls_is_held_to_one_budget() -> None:
    """Each of this cell's ~50 calls stays within the per-call budget (about 1e6 steps of
    slip at |v - V| ~ 1e12 per window segment); the cell as a whole would take 5e7 steps
    and ~17 s, and is stopped at MAX_STEPS_PER_CALL instead."""
    p = OscillatorParams(lam=0.05, eta=0.6, nu=1e12, u0=0.0, V=1e12, b1=0.2, b3=1e-12)
    labels, stats, _, status = cell_statistics([p])
    assert status[0] == STATUS_STEP_BUDGET
    assert labels[0] == Regime.UNRESOLVED
    assert stats[0, ST_N_STEPS] <= MAX_STEPS_PER_CALL



def test_a_sweep_cell_takes_the_budget_of_its_settings() -> None:
    p = OscillatorParams.preset("stribeck", u0=1.15, eta=0.6, nu=0.1)
    labels, _, _, status = cell_statistics([p, p], max_steps=100)
    assert list(status) == [STATUS_STEP_BUDGET] * 2
    assert list(labels) == [Regime.UNRESOLVED] * 2
    labels, _, _, status = cell_statistics([p])  # the default budget is ample
    assert status[0] == 0 and labels[0] != Regime.UNRESOLVED
    with pytest.raises(ValueError, match="max_steps must be > 0"):
        cell_statistics([p], max_steps=0.0)


_INTERRUPTED = """
import sys, time
from fricenv import OscillatorParams, OscillatorState, run_stats, simulate
p = {params}
{call}(p, 0.5)  # warm-up
print("ready", flush=True)
try:
    {call}(p, {span}, state={state}, max_steps_per_tau=1e15, max_steps=1e15)
except KeyboardInterrupt:
    print("interrupted", time.perf_counter(), flush=True)
    sys.exit(0)
print("finished", flush=True)
"""


@pytest.mark.slow
@pytest.mark.parametrize("call", ["run_stats", "simulate"])
def test_ctrl_c_stops_a_running_call_within_a_second(call: str) -> None:
    """SIGINT 2 s into a call that would run for minutes: KeyboardInterrupt in the caller
    within INTERRUPT_S."""
    code = _INTERRUPTED.format(params=FAR, state=FAR_STATE, call=call, span=3.8)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "ready", child.stderr.read()
        time.sleep(2.0)
        sent = time.perf_counter()
        child.send_signal(signal.SIGINT)
        line = child.stdout.readline().split()
        child.wait(timeout=60)
    finally:
        child.kill()
    assert line and line[0] == "interrupted", line
    latency = float(line[1]) - sent  # perf_counter is system-wide on Linux
    print(f"\n[{call}] Ctrl-C latency {latency:.3f} s")
    assert latency <= INTERRUPT_S


@pytest.mark.parametrize("b3", [1e6, 1e9, 1e12])
def test_stiff_cubic_slip_gives_one_answer(b3: float) -> None:
    """A large cubic coefficient damps fast slip hard, but slip near the belt speed stays
    soft: the stick fraction converges as b3 grows, rather than a refusal or a wrong
    number (0.0328-0.0330 for b3 = 1e6 .. 1e12 over 100 units)."""
    s = run_stats(OscillatorParams(b3=b3, u0=5.0, nu=1.0), 100.0)
    assert abs(s.stick_fraction - 0.0329) < 3e-4


def test_anti_damped_cubic_slip_names_its_cause() -> None:
    """b3 < 0 runs away; the error said the slip was too stiff for the time resolution."""
    with pytest.raises(SimulationError, match="negative net damping"):
        run_stats(OscillatorParams(b3=-1e4, u0=5.0, nu=1.0), 10.0)
