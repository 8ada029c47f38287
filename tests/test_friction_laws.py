"""Friction laws as modules: the registry, validation, and the exponential Stribeck law
against the independent SciPy reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fricenv
from fricenv import friction
from fricenv.params import FRICTION_LAWS, OscillatorParams
from fricenv.testing.scipy_reference import reference_solution

EXP = "exponential"


def test_registry_names_every_law_once():
    assert list(friction.LAWS) == ["coulomb", "cubic", "exponential"]
    assert sorted(law.code for law in friction.LAWS.values()) == [0, 1, 2]
    assert friction.OWNER == {"b1": "cubic", "b3": "cubic", "vs": EXP, "delta": EXP,
                              "cv": EXP}
    assert set(FRICTION_LAWS) == {"coulomb", "viscous", "stribeck", EXP}


@pytest.mark.parametrize("name", sorted(FRICTION_LAWS))
def test_presets_name_themselves(name):
    p = OscillatorParams.preset(name)
    assert p.law == name
    assert friction.method_for(p.law_spec) == ("exact" if name == "coulomb" else "event")


def test_method_follows_the_law_not_the_coefficients():
    """A law other than Coulomb never runs the closed form, whatever its coefficients."""
    p = OscillatorParams(friction="cubic")  # b1 = b3 = 0, but declared cubic
    assert p.law_spec.name == "cubic" and not p.is_coulomb
    assert fricenv.simulate(p, 1.0).method == "event"
    with pytest.raises(ValueError, match="needs the Coulomb law, got the exponential law"):
        fricenv.simulate(OscillatorParams.preset(EXP), 1.0, method="exact")


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"delta": 1.5}, "delta of the exponential law must be a whole number, got 1.5"),
    ({"delta": 3.0}, r"delta of the exponential law must be >= 1 and <= 2, got 3.0"),
    ({"vs": 0.0}, r"vs of the exponential law must be > 0, got 0.0"),
    ({"cv": -0.1}, r"cv of the exponential law must be >= 0, got -0.1"),
    ({"b1": 0.2}, "b1 belongs to the cubic law, but this plant's law is exponential"),
])
def test_exponential_parameters_are_checked(kwargs, match):
    with pytest.raises(ValueError, match=match):
        OscillatorParams.preset(EXP, **kwargs)


def test_a_law_parameter_needs_its_law():
    with pytest.raises(ValueError, match="vs belongs to the exponential law"):
        OscillatorParams(vs=0.3)
    with pytest.raises(ValueError, match="unknown friction law 'lugre'"):
        OscillatorParams(friction="lugre")


def test_force_is_continuous_at_break_away():
    law = friction.LAWS[EXP]
    values = OscillatorParams.preset(EXP).law_values()
    f = law.force(np.array([1e-12, -1e-12]), values, 2.5, 4.0)
    np.testing.assert_allclose(f, [4.0, -4.0], atol=1e-9)
    assert law.continuous and not friction.LAWS["cubic"].continuous


#: Plants of the exponential law (delta 1 and 2, cv 0 and > 0), each against the reference.
CASES = [
    {"delta": 1.0, "cv": 0.0, "nu": 0.1, "u0": 1.15},
    {"delta": 1.0, "cv": 0.3, "vs": 1.0, "nu": 1.7, "u0": 4.0},
    {"delta": 2.0, "cv": 0.05, "nu": 1.15, "u0": 0.7},
    {"delta": 2.0, "cv": 0.05, "nu": 1.7, "u0": 4.0},
    {"delta": 2.0, "cv": 0.0, "vs": 0.2, "nu": 0.1, "u0": 1.15},
]


@pytest.mark.parametrize("case", CASES)
def test_exponential_matches_scipy(case):
    p = OscillatorParams.preset(EXP, **case)
    _, x_ref, v_ref, _, ev_ref = reference_solution(p, 60.0, rtol=1e-12, atol=1e-13)
    tr = fricenv.simulate(p, 60.0, dt_out=0.1, rtol=1e-12, atol=1e-12)
    assert tr.method == "event"
    assert len(tr.events) == len(ev_ref)
    np.testing.assert_allclose([e["t"] for e in tr.events], [t for t, _ in ev_ref], atol=1e-8)
    assert np.max(np.abs(tr.x - x_ref)) < 2e-9
    assert np.max(np.abs(tr.v - v_ref)) < 1e-8


@pytest.mark.slow
@settings(max_examples=25, deadline=None)
@given(delta=st.sampled_from([1.0, 2.0]), cv=st.sampled_from([0.0, 0.02, 0.3]),
       vs=st.floats(0.2, 2.0), nu=st.floats(0.1, 2.0), u0=st.floats(0.2, 4.0),
       lam=st.sampled_from([0.1, 0.5, 1.0]))
def test_exponential_matches_scipy_at_random(delta, cv, vs, nu, u0, lam):
    p = OscillatorParams.preset(EXP, delta=delta, cv=cv, vs=vs, nu=nu, u0=u0, lam=lam)
    _, x_ref, *_ = reference_solution(p, 40.0, rtol=1e-12, atol=1e-13)
    tr = fricenv.simulate(p, 40.0, dt_out=0.1, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(tr.x - x_ref)) < 1e-7


def test_exponential_runs_in_maps_and_cells():
    """run_stats, regime_map and cell_statistics take the law, and a map cell equals the
    same plant measured alone."""
    p = OscillatorParams.preset(EXP, eta=0.6)
    s = fricenv.run_stats(p.replace(u0=1.0, nu=0.5), 50.0)
    assert 0.0 <= s.stick_fraction <= 1.0
    m = fricenv.regime_map(p, u0=np.array([0.5, 2.0]), nu=np.array([0.37, 1.7]))
    assert m.labels.shape == (2, 2)
    labels, stats, _, status = fricenv.cell_statistics([p.replace(u0=2.0, nu=1.7)])
    assert status[0] == 0 and labels[0] == m.labels[1, 1]


def test_cells_sweep_a_law_parameter():
    from fricenv.cells import cell_inputs
    from fricenv.params import P_LAW, P_LAW_PARAMS
    from fricenv.sweep import SweepSettings

    base = OscillatorParams.preset(EXP)
    cells = cell_inputs(base, {"vs": np.array([0.2, 0.8])}, SweepSettings())
    np.testing.assert_array_equal(cells.P[:, P_LAW_PARAMS], [0.2, 0.8])
    assert (cells.P[:, P_LAW] == friction.LAWS[EXP].code).all()
    with pytest.raises(ValueError, match="vs of the exponential law must be > 0"):
        cell_inputs(base, {"vs": np.array([0.0])}, SweepSettings())
    with pytest.raises(ValueError, match="b1 belongs to the cubic law"):
        cell_inputs(base, {"b1": np.array([0.1])}, SweepSettings())
    poly = cell_inputs(OscillatorParams(), {"b1": np.array([0.0, 0.2])}, SweepSettings())
    assert list(poly.P[:, P_LAW]) == [0, 1] and list(poly.method) == [0, 1]


def test_exponential_scene_keeps_its_law():
    """An episode of the exponential scene runs its law, drawn or not; b1 is not one of its
    parameters."""
    import gymnasium as gym

    from fricenv.params import P_LAW, P_LAW_PARAMS

    env = gym.make("fricenv/StickSlipExponential-v0", randomize=True)
    env.reset(seed=3)
    P = env.unwrapped._P
    assert P[P_LAW] == friction.LAWS[EXP].code
    np.testing.assert_array_equal(P[P_LAW_PARAMS:], [0.4, 2.0, 0.05])
    with pytest.raises(ValueError, match="b1 belongs to the cubic law"):
        env.reset(options={"b1": 0.2})
