"""Write ``tests/golden/golden.npz``: outputs of the simulator, sweeps and environments.

``tests/test_golden.py`` recomputes every entry and compares it bit for bit, so a change
that moves any result by one ulp is seen. Rerun this script only when a result is meant
to change, and say why in the changelog.

Usage: python tests/golden/make_golden.py
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np

import fricenv
from fricenv.params import PAPER_CASES

GOLDEN = Path(__file__).with_name("golden.npz")

#: Cases beyond the paper's Figs. 4-7, one per friction law and one self-excited plant.
EXTRA_CASES: dict[str, tuple[str, dict[str, float]]] = {
    "stribeck": ("stribeck", {"eta": 1 / 9, "u0": 2.0, "nu": 0.5}),
    "viscous": ("viscous", {"eta": 5 / 3, "u0": 3.0, "nu": 1.3}),
    "self_excited": ("coulomb", {"lam": 0.05, "u0": 0.0, "nu": 1.0}),
    "stribeck_self_excited": ("stribeck", {"lam": 0.1, "V": 0.3, "u0": 0.0}),
}
ENV_IDS = ("fricenv/StickSlip-v0", "fricenv/StickSlipSelfExcited-v0")
N_ROLLOUT = 200
T_END = 60.0


def cases() -> Iterator[tuple[str, fricenv.OscillatorParams]]:
    for name, kw in PAPER_CASES.items():
        yield f"fig{name}", fricenv.OscillatorParams(**kw)
    for name, (law, kw) in EXTRA_CASES.items():
        yield name, fricenv.OscillatorParams.preset(law, **kw)


def simulations() -> Iterator[tuple[str, np.ndarray]]:
    for name, p in cases():
        methods = ["event", "rk4"] + (["exact"] if p.is_coulomb else [])
        for method in methods:
            tr = fricenv.simulate(p, T_END, method=method, dt_out=0.25)
            key = f"simulate/{name}/{method}"
            yield f"{key}/t", tr.t
            yield f"{key}/x", tr.x
            yield f"{key}/v", tr.v
            yield f"{key}/mode", tr.mode
            yield f"{key}/event_t", tr.event_t
            yield f"{key}/event_kind", tr.event_kind
            yield f"{key}/event_x", tr.event_x
            yield f"{key}/stats", _stats_array(tr.stats)
        s = fricenv.run_stats(p, 150.0)
        yield f"run_stats/{name}", _stats_array(s)
        s2 = fricenv.run_stats(p.replace(u0=p.u0 + 0.5), 40.0, state=s.state)
        yield f"run_stats/{name}/continued", _stats_array(s2)


def _stats_array(s: fricenv.RunStats) -> np.ndarray:
    st = s.state
    return np.array([s.duration, s.stick_time, s.n_stick, s.n_slip, s.n_reversals, s.v_max,
                     s.v_min, s.x_max, s.x_min, s.vr2_integral, s.n_steps,
                     st.t, st.x, st.v, st.mode, st.phase1, st.phase2], dtype=float)


def regime_maps() -> Iterator[tuple[str, np.ndarray]]:
    u0 = np.geomspace(0.2, 20.0, 5)
    nu = np.array([0.1, 0.5, 1.3, 2.0])
    for law, eta in (("coulomb", 0.6), ("viscous", 5 / 3), ("stribeck", 0.6)):
        m = fricenv.regime_map(fricenv.OscillatorParams.preset(law, eta=eta), u0, nu,
                               progress=False)
        yield f"regime_map/{law}/labels", m.labels
        yield f"regime_map/{law}/stats", m.stats
        yield f"regime_map/{law}/period", m.period
        yield f"regime_map/{law}/status", m.status


def rollouts() -> Iterator[tuple[str, np.ndarray]]:
    for env_id in ENV_IDS:
        name = env_id.split("/")[1]
        env = gym.make(env_id)
        yield from _rollout(f"env/{name}/single", env.action_space.seed, env.reset,
                            env.step, env.action_space.sample)
        env.close()
        venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
        yield from _rollout(f"env/{name}/vector", venv.action_space.seed, venv.reset,
                            venv.step, venv.action_space.sample)
        venv.close()
        env = gym.make(env_id, randomize=True)
        yield from _rollout(f"env/{name}/randomized", env.action_space.seed, env.reset,
                            env.step, env.action_space.sample)
        env.close()


def _rollout(key: str, seed_actions: Callable, reset: Callable, step: Callable,
             sample: Callable) -> Iterator[tuple[str, np.ndarray]]:
    seed_actions(7)
    obs, _ = reset(seed=3)
    obs_l, rew_l, term_l, trunc_l, act_l = [np.asarray(obs)], [], [], [], []
    for _ in range(N_ROLLOUT):
        a = sample()
        obs, r, term, trunc, _ = step(a)
        act_l.append(np.asarray(a))
        obs_l.append(np.asarray(obs))
        rew_l.append(np.asarray(r, dtype=float))
        term_l.append(np.asarray(term))
        trunc_l.append(np.asarray(trunc))
        if np.ndim(term) == 0 and (term or trunc):
            obs, _ = reset()
            obs_l.append(np.asarray(obs))
    yield f"{key}/obs", np.array(obs_l)
    yield f"{key}/reward", np.array(rew_l)
    yield f"{key}/terminated", np.array(term_l)
    yield f"{key}/truncated", np.array(trunc_l)
    yield f"{key}/action", np.array(act_l)


def compute() -> dict[str, np.ndarray]:
    """Every golden entry, computed by the code at hand."""
    out: dict[str, np.ndarray] = {}
    for part in (simulations, regime_maps, rollouts):
        for k, v in part():
            out[k] = np.asarray(v)
    return out


def main() -> None:
    data = compute()
    np.savez_compressed(GOLDEN, **data)
    print(f"{len(data)} arrays written to {GOLDEN}")


if __name__ == "__main__":
    main()
