"""A Coulomb workload compiles only the closed form: no Taylor or Rosenbrock kernel.

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
import gymnasium as gym
import numpy as np
import fricenv
from fricenv.core import event, rosenbrock, roots, taylor

p = fricenv.OscillatorParams.preset("coulomb", u0=1.0, nu=0.5)
fricenv.simulate(p, 2.0, dt_out=0.5)
fricenv.run_stats(p, 2.0)
fricenv.cell_statistics([p], transient_min=1.0, window_min=1.0, n_strobe=2)
env = gym.make("fricenv/StickSlip-v0")
env.reset(seed=0)
env.step(env.action_space.sample())
kernels = {"taylor._taylor_coeffs": taylor._taylor_coeffs, "taylor._taylor_vr2":
           taylor._taylor_vr2, "taylor._dense_v": taylor._dense_v, "taylor._dense_x":
           taylor._dense_x, "rosenbrock._ros4_step": rosenbrock._ros4_step,
           "event._run_event": event._run_event, "roots._bracket_dense": roots._bracket_dense}
print(json.dumps({name: len(k.signatures) for name, k in kernels.items()}))
"""


def test_a_coulomb_workload_compiles_no_taylor_or_rosenbrock_kernel(tmp_path: Path) -> None:
    root = str(Path(fricenv.__file__).resolve().parent.parent)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True,
                         env=env, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    compiled = json.loads(out.stdout.strip().splitlines()[-1])
    assert compiled == dict.fromkeys(compiled, 0)
