"""The observation has one owner: its channels are declared once (``fricenv.envs.channels``)
and the maps between plants, observations and actions (``fricenv.envs.observation``) agree
with the environments' kernels."""

from __future__ import annotations

import numpy as np
import pytest

from fricenv.envs import kernels as K
from fricenv.envs import sensors, tables
from fricenv.envs.channels import OBSERVATION, Limits
from fricenv.envs.observation import (
    CHANNELS,
    Plants,
    actions_towards,
    channel_names,
    check_observations,
    draw_ranges,
    initial_modes,
    observe,
    plants_from_observations,
)
from fricenv.envs.setup import EnvSetup
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv


def test_the_layout_names_and_bounds_derive_from_the_channels():
    assert CHANNELS == sensors.CHANNELS == OBSERVATION.names
    assert [name for name, _, _ in tables.OBS.slots] == [c.slot for c in OBSERVATION.channels]
    for c in OBSERVATION.channels:
        assert getattr(tables, c.slot) == getattr(K, c.slot) == OBSERVATION.index(c.name)
    assert tables.N_OBS == K.N_OBS == OBSERVATION.size
    setup = EnvSetup.build("stribeck")
    sc = setup.scene
    low, high = OBSERVATION.box(Limits(sc.x_limit, sc.v_limit, sc.u0_range, sc.nu_range))
    assert np.array_equal(low, setup.observation_space.low)
    assert np.array_equal(high, setup.observation_space.high)
    with pytest.raises(ValueError, match="unknown observation channel 'speed'"):
        OBSERVATION.index("speed")


def test_channel_names_follow_the_sensor_options():
    assert channel_names(EnvSetup.build("paper")) == list(CHANNELS)
    picked = channel_names(EnvSetup.build("paper", observe=("phases", "x")))
    assert picked == ["x", "cos1", "sin1", "cos2", "sin2"]


def test_observe_is_the_environments_observation():
    """The vectorised map gives, rounded to float32, what the kernels wrote (the tones'
    cos/sin to the last bits of the core's carried values)."""
    venv = StickSlipVectorEnv(num_envs=3, scene="self_excited")
    obs, _ = venv.reset(seed=2)
    setup = EnvSetup.build("self_excited")
    rng = np.random.default_rng(0)
    for _ in range(5):
        obs, *_ = venv.step(rng.uniform(-1, 1, (3, 2)).astype(np.float32))
        plants, _ = venv.state_arrays()
        mine = observe(plants, setup).astype(np.float32)
        exact = [CHANNELS.index(c) for c in ("x", "v_rel", "stick", "u0", "nu")]
        assert np.array_equal(mine[:, exact], obs[:, exact])
        assert np.allclose(mine, obs, rtol=0, atol=1e-6)
    venv.close()


def test_plants_name_the_columns_of_plant_vectors():
    env = StickSlipEnv(scene="paper")
    env.reset(seed=3)
    state = env.get_state()
    p = Plants(state.plant[None].copy())
    assert (p.x[0], p.v[0], p.mode[0], p.u0[0], p.nu[0]) == (
        state.x, state.v, state.mode, state.u0, state.nu)
    assert p.param("lam")[0] == state.params["lam"] and p.param("eta")[0] == state.params["eta"]
    p.x += 1.0  # a view: writes go through
    assert p.table[0] is not state.plant and p.x[0] == state.x + 1.0
    p.nu = 2.0
    p.drive((1.0, 1.0))
    assert p.param("w2")[0] == 2.0 * p.param("eta")[0]
    with pytest.raises(ValueError, match="unknown plant parameter 'mu'"):
        p.param("mu")
    with pytest.raises(ValueError, match=r"float64 array \(m, "):
        Plants(np.zeros(3))


def test_initial_modes_and_the_inverse_map_agree_with_the_kernels():
    rng = np.random.default_rng(1)
    setup = EnvSetup.build("stribeck")
    P = np.tile(setup.scene.params.to_array(), (50, 1))
    x, phi1, phi2 = rng.uniform(-3, 3, 50), *rng.uniform(0, 6.3, (2, 50))
    v = np.where(rng.random(50) < 0.5, setup.scene.params.V, rng.uniform(-1, 1, 50))
    want = [K.initial_mode(P[i], x[i], v[i], phi1[i], phi2[i]) for i in range(50)]
    assert np.array_equal(initial_modes(P, x, v, phi1, phi2), want)
    env = StickSlipEnv(scene="stribeck")
    obs, _ = env.reset(seed=5)
    true = Plants(env.get_state().plant[None].copy())
    plants, cmds = plants_from_observations(obs[None], true.params[0], (1.0, 1.0))
    est = Plants(plants)
    assert est.mode[0] == true.mode[0] and est.x[0] == pytest.approx(true.x[0], abs=1e-6)
    assert np.array_equal(cmds, est.setting)
    assert list(draw_ranges(setup))[-4:] == ["x0", "v0", "phi1", "phi2"]


@pytest.mark.parametrize("incremental", [False, True])
def test_actions_towards_reach_the_target_setting(incremental):
    setup = EnvSetup.build("self_excited", incremental=incremental)
    env = StickSlipEnv(scene="self_excited", incremental=incremental)
    obs, _ = env.reset(seed=0)
    u0, nu = CHANNELS.index("u0"), CHANNELS.index("nu")
    target = (0.5, 1.5)
    for _ in range(40):
        a = actions_towards(setup, target, (obs[None, u0], obs[None, nu]))
        assert a.dtype == np.float32 and a.shape == (1, 2)
        obs = env.step(a[0])[0]
    assert obs[u0] == pytest.approx(target[0], abs=1e-6)
    assert obs[nu] == pytest.approx(target[1], abs=1e-6)


def test_check_observations_names_what_no_environment_gives():
    setup = EnvSetup.build("self_excited")
    obs, _ = StickSlipEnv(scene="self_excited").reset(seed=0)
    assert check_observations(obs, setup).shape == (1, 9)
    x, stick = CHANNELS.index("x"), CHANNELS.index("stick")
    for value, where, match in ((np.nan, x, r"observation 1, channel 'x' = nan"),
                                (1e30, x, r"channel 'x' = 1e\+30.*within \["),
                                (0.5, stick, r"channel 'stick' = 0.5.*0 or 1")):
        bad = np.stack([obs, obs])
        bad[1, where] = value
        with pytest.raises(ValueError, match=match):
            check_observations(bad, setup)
    with pytest.raises(ValueError, match="empty batch"):
        check_observations(np.zeros((0, 9)), setup)
    with pytest.raises(ValueError, match=r"shape \(9,\) or \(n, 9\)"):
        check_observations(np.zeros((2, 5)), setup)
    # a noisy stick flag reads anything in [0, 1]
    noisy = EnvSetup.build("self_excited", obs_noise={"stick": 0.1})
    half = obs.copy()
    half[stick] = 0.5
    check_observations(half, noisy)
