"""Compare two ways of sharing a vector environment's plants between numba threads.

A: the environment's own parallel kernel (``steppers.EXACT.step_batch_parallel``) as it is.
B: the same per-plant body in a plain ``for i in prange(n)`` loop, which numba cuts into
one contiguous share per thread and hands to its threading layer.

Both step twin ``StickSlipVectorEnv``s of the ``paper`` scene (same seed, same actions)
through ``env.step``, the Python around the kernel included, on every plant count even
below the environment's own parallel threshold. Rounds alternate A, B / B, A; each round
is a few milliseconds of steps, so that a loaded host's slow spells fall on both alike.
Printed per plant count: the median time per step of each, the ratio of the medians B / A,
and the 10th-90th percentile of the per-round ratios. At the end the twins' observations
are compared bit for bit.

Usage: ``python scripts/bench_vector_schedule.py [--sizes 16 256 4096] [--rounds 60]
[--round-ms 4] [--json out.json]``
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable

import numba
import numpy as np
from numba import prange

import fricenv
from fricenv.core import advance_exact_ws
from fricenv.envs import steppers, vector
from fricenv.envs.batch import _count, first_bad_action, step_range_with
from fricenv.envs.tables import F_AUTORESET, IV_MAX_STEPS, IV_MODE
from fricenv.envs.vector import StickSlipVectorEnv
from fricenv.jit import kernel


@kernel(parallel=True)
def step_batch_prange(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
    """``batch.step_batch_with`` by the closed form, its plants in a plain ``prange``."""
    mode = ivars[IV_MODE]
    bad = first_bad_action(A, flags[F_AUTORESET], mode)
    if bad >= 0:
        return -(bad + 1)
    max_steps = ivars[IV_MAX_STEPS]
    for i in prange(table.shape[0]):
        step_range_with(advance_exact_ws, i, i + 1, table, cfg, A, obs, res, flags, counters,
                        draws, bounds, max_steps, mode)
    return _count(flags, counters, draws.shape[1], ivars)


def _env(n: int, kernel_fn: Callable | None) -> StickSlipVectorEnv:
    env = StickSlipVectorEnv(num_envs=n, scene="paper")
    assert env._steppers is steppers.EXACT, env._steppers.name
    env._step_kernel = kernel_fn or env._steppers.step_batch_parallel  # also below 64 plants
    env.reset(seed=1)
    return env


def _stepper(env: StickSlipVectorEnv, actions: np.ndarray) -> Callable[[int], float]:
    """Seconds per step over ``steps`` steps; counts in ``run.serial`` the steps that the
    late-worker back-off sent to one thread."""
    state = {"k": 0}

    def run(steps: int) -> float:
        t = time.perf_counter()
        for _ in range(steps):
            run.serial += env._serial_left > 0  # type: ignore[attr-defined]
            env.step(actions[state["k"] % len(actions)])
            state["k"] += 1
        return (time.perf_counter() - t) / steps

    run.serial = 0  # type: ignore[attr-defined]

    return run


def compare(n: int, rounds: int, round_ms: float) -> dict:
    """Alternating rounds of A and B at ``n`` plants; seconds per step and their ratios."""
    rng = np.random.default_rng(0)
    a_env, b_env = _env(n, None), _env(n, step_batch_prange)
    actions = rng.uniform(-1, 1, (256, *a_env.action_space.shape)).astype(np.float32)
    run = {"A": _stepper(a_env, actions), "B": _stepper(b_env, actions)}
    for fn in run.values():
        fn(5)  # compile or load, and fault the tables in
    per_step = min(fn(5) for fn in run.values())  # (both, so the twins stay in step)
    steps = max(2, int(round_ms * 1e-3 / max(per_step, 1e-7)))
    times: dict[str, list[float]] = {"A": [], "B": []}
    for r in range(rounds):
        for name in ("AB" if r % 2 == 0 else "BA"):
            times[name].append(run[name](steps))
    ratios = [b / a for a, b in zip(times["A"], times["B"], strict=True)]
    q = statistics.quantiles(ratios, n=10)
    same = all(np.array_equal(x, y, equal_nan=True) for x, y in
               ((a_env._obs, b_env._obs), (a_env._res, b_env._res), (a_env._table, b_env._table)))
    return {"plants": n, "steps_per_round": steps, "rounds": rounds,
            "A_us": statistics.median(times["A"]) * 1e6,
            "B_us": statistics.median(times["B"]) * 1e6,
            "ratio_B_over_A": statistics.median(times["B"]) / statistics.median(times["A"]),
            "ratio_p10": q[0], "ratio_p90": q[-1], "identical": same,
            "A_serial_share": run["A"].serial / (10 + rounds * steps)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 256, 4096])
    ap.add_argument("--rounds", type=int, default=60)
    ap.add_argument("--round-ms", type=float, default=4.0)
    ap.add_argument("--json", default=None)
    ap.add_argument("--no-backoff", action="store_true",
                    help="A without the late-worker back-off (the scheduler alone)")
    args = ap.parse_args()
    if args.no_backoff:
        vector.LATE_STEPS = 10**9  # (read by StickSlipVectorEnv._watch_workers)
    info = fricenv.threading_info()
    print(f"threading layer {info.layer}, {numba.get_num_threads()} threads")
    out = []
    for n in args.sizes:
        r = compare(n, args.rounds, args.round_ms)
        out.append(r)
        print(f"{n:5d} plants: A {r['A_us']:9.1f} us  B {r['B_us']:9.1f} us  "
              f"B/A {r['ratio_B_over_A']:.3f} (rounds p10-p90 {r['ratio_p10']:.3f}-"
              f"{r['ratio_p90']:.3f}, {r['steps_per_round']} steps a round)  "
              f"A serial {r['A_serial_share']:.1%}, identical={r['identical']}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"layer": info.layer, "threads": numba.get_num_threads(), "runs": out},
                      f, indent=1)


if __name__ == "__main__":
    main()
