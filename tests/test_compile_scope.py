"""A Coulomb workload compiles only the closed form (no Taylor or Rosenbrock kernel), each
kernel once, and a second process loads all of it from the cache (the parallel vector step
included: a kernel that reads numba's thread count cannot be cached).

Checked in a fresh process with an empty numba cache, where every kernel a workload needs
is compiled (with a warm cache the callers load whole and compile nothing).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import fricenv

_SCRIPT = """
import json
import sys
import gymnasium as gym
import numpy as np
from numba.core import event as numba_event
from numba.core.registry import CPUDispatcher
import fricenv
from fricenv.core import event, rosenbrock, roots, taylor

compiles = numba_event.RecordingListener()
numba_event.register("numba:compile", compiles)

p = fricenv.OscillatorParams.preset("coulomb", u0=1.0, nu=0.5)
fricenv.simulate(p, 2.0, dt_out=0.5)
fricenv.run_stats(p, 2.0)
fricenv.cell_statistics([p], transient_min=1.0, window_min=1.0, q_max=0, n_strobe=2)
env = gym.make("fricenv/StickSlip-v0")
env.reset(seed=0)
env.step(env.action_space.sample())
vec = gym.make_vec("fricenv/StickSlip-v0", num_envs=64, vectorization_mode="vector_entry_point")
vec.reset(seed=0)  # (64 plants: the parallel step kernel)
vec.step(vec.action_space.sample())
kernels = {"taylor._taylor_coeffs": taylor._taylor_coeffs, "taylor._taylor_vr2":
           taylor._taylor_vr2, "taylor._dense_v": taylor._dense_v, "taylor._dense_x":
           taylor._dense_x, "rosenbrock._ros4_step": rosenbrock._ros4_step,
           "event._run_event": event._run_event, "roots._bracket_dense": roots._bracket_dense}
signatures = {f"{m}.{k}": [str(sig) for sig in d.signatures]
              for m in list(sys.modules) if m.startswith("fricenv")
              for k, d in vars(sys.modules[m]).items() if isinstance(d, CPUDispatcher)}
signatures.update({f"partial_kernel.{k}": [str(sig) for sig in d.signatures]
                   for k, d in fricenv.core.partial_kernels().items()})
print(json.dumps({"taylor": {name: len(k.signatures) for name, k in kernels.items()},
                  "compiles": sum(1 for _, e in compiles.buffer if e.is_start),
                  "signatures": signatures}))
"""


def _run_workload(cache: Path) -> dict:
    root = str(Path(fricenv.__file__).resolve().parent.parent)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True,
                         env=env, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "NumbaWarning" not in out.stderr, out.stderr[-3000:]  # e.g. "Cannot cache"
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_coulomb_workload_compiles_each_kernel_once_and_once_only(tmp_path: Path) -> None:
    """From an empty cache: no Taylor or Rosenbrock kernel, one signature per kernel (a
    constant passed as an argument once compiled a kernel per value). Then a second
    process on the same cache compiles nothing: every kernel is cacheable."""
    first = _run_workload(tmp_path / "cache")
    assert first["taylor"] == dict.fromkeys(first["taylor"], 0)
    assert first["compiles"] > 0
    several = {k: sigs for k, sigs in first["signatures"].items() if len(sigs) > 1}
    assert not several, several
    second = _run_workload(tmp_path / "cache")
    assert second["compiles"] == 0


def test_the_closed_form_runs_every_plant_damped_past_lam_conditioned() -> None:
    """steppers_for and always_conditioned rely on it: from LAM_CONDITIONED on, no tone
    is too close to resonance for the closed form, whatever its frequency."""
    import numpy as np

    from fricenv.core import closed_form_conditioned
    from fricenv.core.constants import LAM_CONDITIONED
    from fricenv.params import OscillatorParams

    rng = np.random.default_rng(0)
    near = 1.0 + np.concatenate([rng.uniform(-2e-3, 2e-3, 400), [0.0, 1e-16, -1e-16]])
    for lam in (LAM_CONDITIONED, 1.001 * LAM_CONDITIONED, 0.01, 0.5):
        for w in near:
            P = OscillatorParams.preset("coulomb", lam=lam, eta=float(w), u0=1.0,
                                        nu=1.0).to_array()
            assert closed_form_conditioned(P), (lam, w)
    # below it, some tone near w = 1 is not
    P = OscillatorParams.preset("coulomb", lam=1e-4, eta=1.0 + 1e-4, u0=1.0,
                                nu=1.0).to_array()
    assert not closed_form_conditioned(P)


def test_each_environment_runs_the_narrowest_kernels_for_its_plants() -> None:
    import gymnasium as gym

    from fricenv.envs import steppers

    def chosen(**kw) -> str:
        env = gym.make("fricenv/StickSlip-v0", disable_env_checker=True, **kw).unwrapped
        env.reset(seed=0)
        return env._steppers.name

    assert chosen() == "exact"  # Coulomb, lambda = 1/2
    assert chosen(randomize=True) == "exact"  # lambda in [0.4, 0.6]
    assert chosen(method="event") == "event"
    assert chosen(params={"b1": 0.1}) == "event"
    assert chosen(params={"lam": 0.0}) == "any"  # a tone may meet resonance: both methods
    vec = gym.make_vec("fricenv/StickSlip-v0", num_envs=2,
                       vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    assert vec.unwrapped._steppers is steppers.EXACT
    vec.reset(seed=0, options={"b1": 0.1})  # the plants' law changes: so do the kernels
    assert vec.unwrapped._steppers is not steppers.EXACT


def test_a_kernel_inlined_as_called_once_has_one_call_site() -> None:
    """``kernel(called_once=True)`` inlines at numba's IR level, which costs no compile
    time only while the body has a single caller to be typed in."""
    import re

    sources = [p.read_text() for p in Path(fricenv.__file__).resolve().parent.rglob("*.py")]
    once = [m.group(1) for s in sources for m in re.finditer(
        r"@kernel\([^)]*called_once=True[^)]*\)\s*\ndef (\w+)\(", s)]
    assert once
    text = "\n".join(sources)
    for name in once:  # calls by name or through a module (friction.add_accel), not defs
        calls = re.findall(rf"(?<!def )(?<!\w){name}\(", text)
        assert len(calls) == 1, f"{name}: {len(calls)} call sites"
