"""Every public call answers: it returns a sound result or raises a documented exception.

A property suite over the entry points (``run_stats``, ``simulate``, ``cell_statistics``,
``regime_map`` with its file, ``RegimeMap.load`` of damaged files, the environment's
reset, step and ``sample_interval``, the vector environment), with parameters, starting
states and sizes from ordinary values out to the documented limits. Each call runs in a
worker process (``callcheck.py``) under a time budget that only detects hangs; the
worker judges the answer: no statistic inf or NaN while the status says OK, no motion
beyond the bound of ``fricenv.divergence`` presented as a result, a stick time at most
its duration, a block stuck all window long labelled STUCK (``callcheck`` lists it all).

Region left out until the kernels honour a step budget (``scripts/stress.py`` keeps
reproducers of both): stiff slip, ``|b1| + 3 |b3| v_r^2`` beyond ``STIFF_MAX`` at the
speeds the plant's forces and start reach (b1 = b3 = 1e8: 0.3 s for 4 units of time;
1e10: 16 s; 1e12: minutes; a Stribeck start at x0 = 1e12: 3e7 steps per unit), and calls
whose scan alone (``core.most_scan_steps``: half a radian of the fastest tone, 1 / rate
when over-damped) needs more than ``SCAN_FLOOR_MAX`` steps: ``simulate.MAX_SCAN_STEPS``
allows 1e9, minutes of work. Everything else goes to the limits.

The default run draws ``EXAMPLES`` calls per entry; the ``slow`` run ten times as many.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fricenv.core import most_scan_steps
from fricenv.envs.vector import MAX_NUM_ENVS
from fricenv.params import P_W1, P_W2, OscillatorParams
from fricenv.sweep import SweepSettings, plan_cells

sys.path.insert(0, str(Path(__file__).resolve().parent))

from callcheck import WARM_UP, Worker  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: Seconds a call may take before it counts as a hang: detection only (the calls drawn
#: here take milliseconds to a few seconds on a busy machine).
BUDGET_S = 120.0
EXAMPLES = 20
#: Largest |b1|, |b3| drawn with a cubic law, and largest slip stiffness
#: |b1| + 3 |b3| v_r^2 at the speeds its forces and start allow (module docstring).
CUBIC_COEF_MAX = 1e3
STIFF_MAX = 1e6
#: Most scan steps a call drawn here may need (module docstring).
SCAN_FLOOR_MAX = 1e6
ENV_IDS = ("fricenv/StickSlip-v0", "fricenv/StickSlipSelfExcited-v0")


@pytest.fixture(scope="module")
def worker():
    w = Worker(str(ROOT), WARM_UP)
    yield w
    w.close()


def answers(worker: Worker, entry: str, kwargs: dict) -> None:
    out = worker.call(entry, kwargs, BUDGET_S)
    assert out.ok, f"{entry}({kwargs}) -> {out}"


def _prop(n: int = EXAMPLES):
    return settings(max_examples=n, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much])


# -- strategies ---------------------------------------------------------------------------
def magnitude(lo: int = -12, hi: int = 12, zero: bool = True) -> st.SearchStrategy[float]:
    """0, powers of ten from 1e``lo`` to 1e``hi`` (the documented limit is 1e12), and
    ordinary values."""
    parts = [st.integers(lo, hi).map(lambda e: 10.0 ** e), st.floats(0.01, 10.0)]
    return st.one_of(st.just(0.0), *parts) if zero else st.one_of(*parts)


signed = st.builds(lambda m, s: m * s, magnitude(), st.sampled_from([1.0, -1.0]))


@st.composite
def plants(draw, cubic_ok: bool = True) -> dict:
    """A plant of any law: Fig. 2's, negative net damping, a negative cubic term, or
    extreme coefficients (kept out of the stiff-slip region, module docstring)."""
    law = draw(st.sampled_from(["coulomb", "viscous", "stribeck", "anti", "cubic"]
                               if cubic_ok else ["coulomb", "viscous", "anti"]))
    b1, b3 = {"coulomb": (0.0, 0.0), "viscous": (0.2, 0.0), "stribeck": (0.2, 0.16),
              "anti": (draw(st.floats(0.0, 5.0)), 0.0),
              "cubic": (draw(st.floats(-CUBIC_COEF_MAX, CUBIC_COEF_MAX)),
                        draw(st.floats(-CUBIC_COEF_MAX, CUBIC_COEF_MAX)))}[law]
    xfk = draw(st.one_of(st.just(2.5), magnitude()))
    p = {"lam": draw(st.one_of(st.just(0.5), magnitude(hi=6))),
         "eta": draw(st.one_of(st.just(0.6), magnitude(zero=False))),
         "nu": draw(magnitude()), "u0": draw(magnitude()),
         "V": draw(st.one_of(st.just(1.0), magnitude())),
         "xfk": xfk, "xfs": xfk + draw(st.one_of(st.just(1.5), magnitude())),
         "b1": b1, "b3": b3}
    p["xfs"] = min(p["xfs"], max(xfk, 1e12))
    for k in ("u0", "V", "xfk", "xfs"):  # the forces, and so the speeds, they set
        p[k] = min(p[k], _speed_max(p))
    return p


def _speed_max(p: dict) -> float:
    """A third of the slip speed at which the cubic law reaches STIFF_MAX (1e12 without
    one): forces and starting state each up to it keep the plant out of stiff slip."""
    if p["b3"] == 0.0:
        return 1e12
    return math.sqrt(max(STIFF_MAX - abs(p["b1"]), 0.0) / (3.0 * abs(p["b3"]))) / 3.0


def start(p: dict) -> st.SearchStrategy[tuple[float, float]]:
    limit = _speed_max(p)
    state = st.one_of(st.just(0.0), signed).map(lambda x: max(-limit, min(limit, x)))
    return st.tuples(state, state)


def span(p: dict) -> st.SearchStrategy[float]:
    try:  # the scan-step floor per unit of time
        rate = most_scan_steps(OscillatorParams(**p).to_array()[None], np.ones(1))[0]
    except ValueError:  # a plant the call refuses anyway
        rate = 0.0
    return st.floats(1e-3, min(1e3, max(1e-3, SCAN_FLOOR_MAX / max(rate, 1e-300))))


def cells_floor(ps: list[dict], settings_: dict) -> float:
    """The most scan steps a cell of these plants needs (span: transient and windows)."""
    sweep_settings = SweepSettings(**settings_)
    most = 0.0
    for p in ps:
        try:
            params = OscillatorParams(**p)
            plan = plan_cells(params, np.array([params.nu]), sweep_settings)
        except ValueError:
            continue
        longest = plan.t_transient + plan.t_segment * plan.n_segment * np.maximum(plan.tries, 1)
        P = params.to_array()[None]
        P[0, P_W2] = plan.nu_exact[0] * P[0, P_W1]
        most = max(most, most_scan_steps(P, longest.astype(float))[0])
    return most


# -- the properties -----------------------------------------------------------------------
def _run_stats_case(draw) -> tuple[str, dict]:
    p = draw(plants())
    x0, v0 = draw(start(p))
    return "run_stats", {"params": p, "t_span": draw(span(p)), "x0": x0, "v0": v0,
                         "method": draw(st.sampled_from(["auto", "event"]))}


def _simulate_case(draw) -> tuple[str, dict]:
    p = draw(plants())
    x0, v0 = draw(start(p))
    t = draw(span(p))
    return "simulate", {"params": p, "t_end": t, "x0": x0, "v0": v0,
                        "method": draw(st.sampled_from(["auto", "event", "rk4"])),
                        "dt_out": max(t / 50, 1e-3)}


@st.composite
def run_cases(draw) -> tuple[str, dict]:
    return draw(st.sampled_from([_run_stats_case, _simulate_case]))(draw)


@st.composite
def sweep_cases(draw) -> tuple[str, dict]:
    # short cells (a few tens of time units), which still test integer nu for periodicity
    settings_ = {"x0": 0.0, "v0": 0.0, "transient_min": 10.0, "window_min": 10.0,
                 "transient_periods": 0.1, "window_periods": 0.1, "transient_efolds": 0.0,
                 "q_max": 1, "m_max": 2, "n_strobe": 5, "lock_extensions": 0}

    if draw(st.booleans()):
        ps = draw(st.lists(plants(), min_size=1, max_size=3))
        assume(cells_floor(ps, settings_) <= SCAN_FLOOR_MAX)
        return "cell_statistics", {"params": ps, "settings": settings_}
    p = draw(plants())
    grid = st.lists(magnitude(hi=12 if p["b3"] == 0.0 else 4), min_size=1, max_size=3,
                    unique=True)
    u0, nu = draw(grid), draw(grid)
    assume(cells_floor([{**p, "u0": a, "nu": b} for a in u0 for b in nu], settings_)
           <= SCAN_FLOOR_MAX)
    return "regime_map", {"params": {k: v for k, v in p.items() if k not in ("u0", "nu")},
                          "u0": u0, "nu": nu, "settings": settings_,
                          "save": draw(st.booleans())}


@st.composite
def env_cases(draw) -> tuple[str, dict]:
    env_id = draw(st.sampled_from(ENV_IDS))
    p = draw(plants(cubic_ok=draw(st.booleans())))
    options = {k: p[k] for k in ("lam", "eta", "V", "xfk", "xfs", "b1", "b3")
               if draw(st.booleans())}
    if draw(st.booleans()):
        options["x0"], options["v0"] = draw(start(p))
    n_act = 1 if env_id == ENV_IDS[0] else 2
    action = st.lists(st.floats(-1.0, 1.0), min_size=n_act, max_size=n_act)
    if draw(st.booleans()):
        return "vector", {"env_id": env_id, "num_envs": draw(st.one_of(  # (or refused)
            st.integers(1, 70), st.integers(0, 3).map(lambda e: 10 ** e),
            st.integers(MAX_NUM_ENVS + 1, 10**18))),
            "make": {"randomize": draw(st.booleans())}, "options": options or None,
            "steps": draw(st.integers(1, 5))}
    return "env", {"env_id": env_id, "make": {}, "options": options or None,
                   "actions": draw(st.lists(action, min_size=1, max_size=10)),
                   "sample": draw(st.one_of(st.none(), st.integers(1, 200),
                                            st.integers(0, 12).map(lambda e: 10 ** e)))}


@pytest.fixture(scope="module")
def map_bytes(tmp_path_factory) -> bytes:
    import fricenv

    path = tmp_path_factory.mktemp("map") / "m.npz"
    fricenv.regime_map("coulomb", [0.5, 3.0], [0.5, 1.3], progress=False).save(path)
    return path.read_bytes()


def _damaged(data: bytes, changes: list[tuple[int, int]], cut: int | None) -> bytes:
    b = bytearray(data)
    for k, value in changes:
        b[k % len(b)] = value
    return bytes(b[:cut] if cut is not None else b)


changes = st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), max_size=3)
cuts = st.one_of(st.none(), st.integers(0, 10**4))


@_prop()
@given(case=run_cases())
def test_runs_answer(worker, case) -> None:
    answers(worker, *case)


@_prop()
@given(case=sweep_cases())
def test_sweeps_answer(worker, case) -> None:
    answers(worker, *case)


@_prop()
@given(case=env_cases())
def test_environments_answer(worker, case) -> None:
    answers(worker, *case)


@_prop()
@given(changes=changes, cut=cuts)
def test_damaged_map_files_answer(worker, map_bytes, changes, cut) -> None:
    answers(worker, "load", {"data": _damaged(map_bytes, changes, cut)})


@pytest.mark.slow
@_prop(10 * EXAMPLES)
@given(case=st.one_of(run_cases(), sweep_cases(), env_cases()))
def test_every_entry_answers_extended(worker, case) -> None:
    answers(worker, *case)


@pytest.mark.slow
@_prop(10 * EXAMPLES)
@given(changes=changes, cut=cuts)
def test_damaged_map_files_answer_extended(worker, map_bytes, changes, cut) -> None:
    answers(worker, "load", {"data": _damaged(map_bytes, changes, cut)})


def test_the_judge_sees_what_it_must(worker) -> None:
    """The worker's judge itself: a wrong answer and a bare error are not 'ok'."""
    out = worker.call("run_stats", {"params": {"lam": 0.0, "b1": 1.0, "u0": 10.0, "nu": 0.3},
                                    "t_span": 1e3}, BUDGET_S)
    assert out.kind == "clear" and "diverged" in out.error  # (returned inf before)
    from callcheck import motion_bound

    import fricenv
    p = fricenv.OscillatorParams(u0=1.0)
    assert motion_bound(p, 0.0, 0.0, 10.0) == pytest.approx(1e8 * 4.0 * 10.0)
    assert math.isfinite(motion_bound(p.replace(b1=1e12, b3=1e-300, lam=0.0), 0, 0, 1))
    assert np.isclose(motion_bound(p, 0.0, 0.0, 10.0), 4e9)
