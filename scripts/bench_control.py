"""Benchmark the control-study pieces, side by side in one process.

The bounds checked (ratios and times on this machine):

1. the unwrapped ``StickSlipEnv.step`` of the Stribeck and viscous scenes (event method)
   <= 1.0x the unwrapped step of Gymnasium's ``Pendulum-v1``;
2. one MPC decision (MPPI, 256 samples x 12 intervals, one iteration, one plant) <= 10 ms;
   reported with its cost per plant-interval against the native vector env's per
   plant-step (256 plants), in Pendulum steps (a yardstick of the machine's speed at the
   time, which a shared machine changes), and beside the default MPC's decision (two
   iterations).

Contenders alternate in rounds after 20 ms idle each and medians are reported (the machine
is shared). Every contender is warmed up first (numba compilation and cache loading are
excluded). The MPC decision is timed from a state 20 steps into an episode, with numba's
threads on and on one thread.

Usage: ``python scripts/bench_control.py [--quick] [--json out.json]``
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
from collections.abc import Callable

import gymnasium as gym
import numpy as np
from fricenv_agents.mpc import DEFAULT_ITERATIONS, MPPIController

from fricenv.bench.env import alternating_rounds
from fricenv.envs import register_envs
from fricenv.envs.vector import StickSlipVectorEnv

MPC_SAMPLES = 256
MPC_HORIZON = 12
DECISION_LIMIT_MS = 10.0
SCENE_IDS = {"stribeck": "fricenv/StickSlipStribeck-v0",
             "viscous": "fricenv/StickSlipViscous-v0",
             "paper": "fricenv/StickSlip-v0",
             "self_excited": "fricenv/StickSlipSelfExcited-v0"}
#: Scenes held to bound 1 (the others are shown for comparison).
EVENT_SCENES = ("stribeck", "viscous")
VECTOR_PLANTS = 256


def _stepper(env, seed: int = 0, n_actions: int = 512) -> Callable[[], None]:
    """Step ``env`` through pre-drawn actions, resetting when an episode ends."""
    rng = np.random.default_rng(seed)
    space = env.action_space
    acts = itertools.cycle(rng.uniform(-1, 1, (n_actions, *space.shape)).astype(np.float32))
    env.reset(seed=seed)

    def step() -> None:
        out = env.step(next(acts))
        if not isinstance(out[2], np.ndarray) and (out[2] or out[3]):
            env.reset()

    return step


def _decider(scene: str, parallel: bool, iterations: int = 1) -> Callable[[], None]:
    """One MPC decision for one plant, 20 steps into an episode."""
    vec = StickSlipVectorEnv(num_envs=1, scene=scene)
    obs, _ = vec.reset(seed=1)
    ctrl = MPPIController(scene, samples=MPC_SAMPLES, horizon=MPC_HORIZON, parallel=parallel,
                          iterations=iterations)
    ctrl.bind(vec)
    for _ in range(20):
        obs = vec.step(ctrl.predict(obs)[0])[0]
    plants, cmds = vec.state_arrays()

    def decide() -> None:
        ctrl.plan(plants, cmds)

    return decide


def bench(quick: bool) -> dict:
    rounds = 5 if quick else 15
    n_single = 2_000 if quick else 5_000
    n_vec = 20 if quick else 60
    n_mpc = 5 if quick else 20
    contenders = {"pendulum": (_stepper(gym.make("Pendulum-v1").unwrapped), n_single)}
    for scene, env_id in SCENE_IDS.items():
        contenders[f"single:{scene}"] = (_stepper(gym.make(env_id).unwrapped), n_single)
        contenders[f"vector:{scene}"] = (_stepper(gym.make_vec(env_id,
                                                               num_envs=VECTOR_PLANTS)), n_vec)
        contenders[f"mpc:{scene}"] = (_decider(scene, True), n_mpc)
        contenders[f"mpc1:{scene}"] = (_decider(scene, False), n_mpc)
        contenders[f"mpcdef:{scene}"] = (_decider(scene, True, DEFAULT_ITERATIONS), n_mpc)
    samples = alternating_rounds(contenders, rounds)
    t = {k: statistics.median(v) for k, v in samples.items()}
    intervals = MPC_SAMPLES * MPC_HORIZON
    out = {"pendulum_step_us": t["pendulum"] * 1e6, "scenes": {}}
    for scene in SCENE_IDS:
        per_plant = t[f"vector:{scene}"] / VECTOR_PLANTS
        mpc = t[f"mpc:{scene}"]
        out["scenes"][scene] = {
            "single_step_us": t[f"single:{scene}"] * 1e6,
            "single_over_pendulum": t[f"single:{scene}"] / t["pendulum"],
            "vector_per_plant_step_us": per_plant * 1e6,
            "mpc_decision_ms": mpc * 1e3,
            "mpc_decision_one_thread_ms": t[f"mpc1:{scene}"] * 1e3,
            "mpc_decision_in_pendulum_steps": mpc / t["pendulum"],
            "default_mpc_decision_ms": t[f"mpcdef:{scene}"] * 1e3,
            "mpc_per_plant_interval_us": mpc / intervals * 1e6,
            "mpc_plant_interval_over_vector_plant_step": mpc / intervals / per_plant,
        }
    return out


def report(r: dict) -> None:
    print(f"Pendulum-v1 unwrapped step: {r['pendulum_step_us']:.2f} us")
    print(f"{'scene':13s} {'step us':>8s} {'/ Pendulum':>10s} {'vector/plant us':>16s} "
          f"{'MPC ms':>7s} {'1-thread':>8s} {'Pendulums':>9s} {'us/interval':>11s} "
          f"{'/ vector':>8s} {'default ms':>10s}")
    for scene, s in r["scenes"].items():
        print(f"{scene:13s} {s['single_step_us']:8.2f} {s['single_over_pendulum']:10.2f} "
              f"{s['vector_per_plant_step_us']:16.3f} {s['mpc_decision_ms']:7.2f} "
              f"{s['mpc_decision_one_thread_ms']:8.2f} "
              f"{s['mpc_decision_in_pendulum_steps']:9.0f} "
              f"{s['mpc_per_plant_interval_us']:11.3f} "
              f"{s['mpc_plant_interval_over_vector_plant_step']:8.2f} "
              f"{s['default_mpc_decision_ms']:10.2f}")
    print("(MPC: one decision, 256 samples x 12 intervals, one iteration, one plant, numba's "
          "threads on; 1-thread: on one; Pendulums: the decision in Pendulum-v1 steps; "
          "us/interval: per plant-interval rolled out, and over the vector env's per "
          "plant-step; default: the default MPC's decision, two iterations)")
    for scene in EVENT_SCENES:
        ratio = r["scenes"][scene]["single_over_pendulum"]
        print(f"bound 1 ({scene}): step / Pendulum = {ratio:.2f} (<= 1.0) "
              f"{'PASS' if ratio <= 1.0 else 'FAIL'}")
    for scene, s in r["scenes"].items():
        ms = s["mpc_decision_ms"]
        print(f"bound 2 ({scene}): MPC decision {MPC_SAMPLES} x {MPC_HORIZON} = {ms:.2f} ms "
              f"(<= {DECISION_LIMIT_MS:g}) {'PASS' if ms <= DECISION_LIMIT_MS else 'FAIL'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    ap.add_argument("--json", help="write the results to this file")
    args = ap.parse_args()
    register_envs()
    r = bench(args.quick)
    report(r)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(r, f, indent=2)


if __name__ == "__main__":
    main()
