"""The particle filter in front of the exact-model MPC: it tracks the plant's exact state
through noise and delay, starts each plant's episode on its own, and checks its input."""

from __future__ import annotations

import numpy as np
import pytest
from fricenv_agents.estimation import (
    FilteredMPC,
    ParticleFilter,
    TrackingProbe,
    noise_retention,
)
from fricenv_agents.rollouts import rollout

from fricenv.envs import kernels as K
from fricenv.envs.observation import initial_modes
from fricenv.envs.rollout import BatchRollout
from fricenv.envs.setup import EnvSetup
from fricenv.envs.state import PL_P, PL_S, PL_WORK
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv
from fricenv.layout import S_PHI1, S_PHI2, S_V, S_X
from fricenv.params import P_V

NOISE = {"x": 0.05, "v_rel": 0.05, "cos1": 0.02, "sin1": 0.02, "cos2": 0.02, "sin2": 0.02}


def _errors(scene: str, kw: dict, steps: int, particles: int = 200,
            seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Absolute errors (steps, plants, 2) of x and v - V of the filter's posterior mean and
    of the raw reading against the exact current states, under random actions."""
    venv = StickSlipVectorEnv(num_envs=2, scene=scene, **kw)
    filt = ParticleFilter(EnvSetup.build(scene, **kw), particles, seed=0)
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    est_err, raw_err = [], []
    for t in range(steps):
        filt.observe(obs, np.full(2, t == 0))
        plants, _ = venv.state_arrays()
        truth = np.stack([plants[:, PL_S + S_X], plants[:, PL_S + S_V] - plants[:, PL_P + P_V]], 1)
        est = filt.estimate()
        est_err.append(np.abs(np.stack([est["x"], est["v_rel"]], 1) - truth))
        raw_err.append(np.abs(obs[:, [K.O_X, K.O_VR]] - truth))
        act = rng.uniform(-1, 1, (2, venv.single_action_space.shape[0])).astype(np.float32)
        filt.applied(act)
        obs, *_ = venv.step(act)
    venv.close()
    return np.array(est_err), np.array(raw_err)


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_filter_tracks_a_noise_free_plant_through_the_delay(delay):
    est, raw = _errors("self_excited", {"obs_delay": delay}, 25)
    assert est.max() < 1e-2
    if delay:  # (the reading itself is d intervals old)
        assert raw[delay + 1:].mean() > 0.05


def test_filter_beats_the_raw_reading_under_noise_and_delay():
    """Plants drawn from the scene's ranges, the benchmark's noise and a one-step delay: the
    posterior mean is much closer to the current state than the reading is."""
    kw = {"randomize": True, "obs_noise": NOISE, "obs_delay": 1}
    est, raw = _errors("viscous", kw, 40, particles=300)
    rms_est = np.sqrt((est[5:] ** 2).mean(axis=(0, 1)))
    rms_raw = np.sqrt((raw[5:] ** 2).mean(axis=(0, 1)))
    assert np.all(rms_est < 0.4 * rms_raw), (rms_est, rms_raw)
    assert np.all(rms_est < 0.06)


def test_filter_starts_each_plant_on_its_own():
    """Plant 0 starts a new episode (another plant) half-way; plant 1 goes on: both track."""
    kw = {"obs_noise": NOISE, "obs_delay": 1}
    a, b = (StickSlipVectorEnv(num_envs=2, scene="viscous", **kw) for _ in range(2))
    filt = ParticleFilter(EnvSetup.build("viscous", **kw), 200, seed=1)
    obs_a, _ = a.reset(seed=10)
    obs_b, _ = b.reset(seed=20)
    rng = np.random.default_rng(0)
    for t in range(16):
        switched = t >= 8
        obs = np.stack([(obs_b if switched else obs_a)[0], obs_a[1]])
        filt.observe(obs, np.array([t in (0, 8), t == 0]))
        if t == 8:
            assert filt._steps.tolist() == [0, 8] and filt._n_acts.tolist() == [0, 1]
        act = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        filt.applied(act)
        pa, pb = a.state_arrays()[0], b.state_arrays()[0]
        obs_a, *_ = a.step(act)
        obs_b, *_ = b.step(act)
    est = filt.estimate()
    truth_x = [pb[0, PL_S + S_X] if switched else pa[0, PL_S + S_X], pa[1, PL_S + S_X]]
    filt.observe(np.stack([obs_b[0], obs_a[1]]), np.zeros(2, bool))
    assert np.abs(est["x"] - truth_x).max() < 0.5  # (the estimate before the last step)
    plants, _ = b.state_arrays()
    assert abs(filt.estimate()["x"][0] - plants[0, PL_S + S_X]) < 0.1


def test_filter_checks_its_input():
    setup = EnvSetup.build("paper", obs_delay=1)
    for kwargs, err, name in (({"particles": 1}, ValueError, "particles"),
                              ({"particles": 2.5}, TypeError, "particles"),
                              ({"resample_below": 0.0}, ValueError, "resample_below"),
                              ({"resample_below": 1.5}, ValueError, "resample_below"),
                              ({"roughening": -0.1}, ValueError, "roughening")):
        with pytest.raises(err, match=name):
            ParticleFilter(setup, **kwargs)
    filt = ParticleFilter(setup, 8)
    with pytest.raises(ValueError, match=r"readings must have shape \(n, 9\)"):
        filt.observe(np.zeros((2, 5)))
    with pytest.raises(ValueError, match="finite"):
        filt.observe(np.full((2, 9), np.nan))
    with pytest.raises(ValueError, match=r"observation 0, channel 'stick' = 0.5"):
        filt.observe(np.full((1, 9), 0.5))
    obs = StickSlipEnv(scene="paper").reset(seed=0)[0][None]
    with pytest.raises(ValueError, match="one flag per plant"):
        filt.observe(obs, np.ones(3, bool))
    with pytest.raises(ValueError, match="plan_from must be one of"):
        FilteredMPC("paper", plan_from="median")
    with pytest.raises(ValueError, match="particles"):
        FilteredMPC("paper", particles=0)
    with pytest.raises(TypeError, match="estimate"):
        TrackingProbe(object())  # type: ignore[arg-type]


def test_modes_match_the_kernels_rule():
    rng = np.random.default_rng(3)
    setup = EnvSetup.build("stribeck", randomize=True)
    P = np.tile(setup.scene.params.to_array(), (200, 1))
    P[:, P_V] = rng.uniform(0.2, 0.4, 200)
    x = rng.uniform(-6, 6, 200)
    v = np.where(rng.random(200) < 0.5, P[:, P_V], rng.uniform(-1, 1, 200))
    phi1, phi2 = rng.uniform(0, 6.3, (2, 200))
    want = [K.initial_mode(P[i], x[i], v[i], phi1[i], phi2[i]) for i in range(200)]
    assert np.array_equal(initial_modes(P, x, v, phi1, phi2), want)


def test_end_states_are_the_environments_next_state():
    env = StickSlipEnv(scene="viscous")
    env.reset(seed=4)
    roll = BatchRollout(env, 1, 1)
    for a in np.array([[0.3, -0.2], [1.0, 1.0], [-1.0, 0.0]], np.float32):
        roll.run(env.get_state(), a[None, None])  # (as the env gets it: float32)
        env.step(a)
        ends, cmds = roll.end_states()
        state = env.get_state()
        assert np.array_equal(ends[0, :PL_WORK], state.plant[:PL_WORK])
        assert np.array_equal(cmds[0], state.command)
        assert ends[0, PL_S + S_PHI1] == state.plant[PL_S + S_PHI1]
        assert ends[0, PL_S + S_PHI2] == state.plant[PL_S + S_PHI2]


def test_filtered_mpc_controls_from_the_readings_alone():
    """A short episode batch under noise and delay, and under partial observation (which the
    unbound MPC refuses): the filtered MPC cuts the stick, and never reads the env."""
    scene = StickSlipEnv(scene="viscous").scene.replace(max_episode_steps=30)
    kw = {"obs_noise": NOISE, "obs_delay": 1, "randomize": True}
    ctrl = FilteredMPC(scene, kw, horizon=6, samples=32, particles=100, seed=2)
    probe = TrackingProbe(ctrl)
    m = rollout(probe, scene, 100, 2, kw)
    assert m.stick_fraction.mean() < 0.25
    assert ctrl._env is None and probe.count == 60
    rms = probe.rms()
    assert rms["x"] < rms["raw_x"] and rms["v_rel"] < rms["raw_v_rel"]
    info = ctrl.describe()
    assert info["particles"] == 100 and info["obs_delay"] == 1
    assert info["label"] == FilteredMPC.label
    partial = {"observe": ("x", "stick", "phases", "settings"), "obs_delay": 1}
    post = FilteredMPC(scene, partial, horizon=6, samples=32, particles=100,
                       plan_from="posterior")
    m = rollout(post, scene, 100, 2, partial)
    assert m.stick_fraction.mean() < 0.25


def test_noise_retention_scores_the_three_mpcs_on_the_same_episodes():
    r = noise_retention("paper", 1, 2, {"randomize": True, "max_episode_steps": 4},
                        {"obs_noise": 0.01, "obs_delay": 1}, particles=50)
    assert r["episodes"] == 2 and set(r["cut"]) == {"exact", "raw", "filtered"}
    assert r["stick"]["zero"] == r["stick"]["zero_sensors"]  # (same plants, no control)
    assert all(len(v) == 2 for v in r["per_episode_stick"].values())
    assert np.isfinite(list(r["retention"].values())).all()
    assert r["rms"]["x"] < r["rms"]["raw_x"] and r["filter"]["particles"] == 50
    with pytest.raises(ValueError, match="n_seeds"):
        noise_retention("paper", 0, 2, {}, {})
