"""Forward sensitivities: which parameters a run may be differentiated by, and the seeds.

A run with ``wrt`` (``simulate``, ``run_stats``) carries, beside the state, its derivative
by each named parameter, exactly through every stick/slip switch (the saltation
conditions of :mod:`fricenv.core.tangent`). This module names what may be differentiated,
turns each name into a seed (what the kernels' quantities move by), and runs the tangent
kernel; the public functions take ``wrt`` and return the derivatives.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from . import calls, friction
from .checks import got
from .layout import STATUS_BUFFER_FULL
from .params import P_LAW, OscillatorParams

#: Every parameter a run may be differentiated by, beside the friction law's own: the
#: plant's, the excitation's and the start state's.
CORE_WRT = ("lam", "eta", "nu", "u0", "u1", "u2", "V", "xfk", "xfs", "x0", "v0")
SINGULAR_DTYPE = np.dtype([("t", "f8"), ("kind", "i1"), ("name", "U24")])


def law_wrt(params: OscillatorParams) -> tuple[str, ...]:
    """The law parameters ``params`` may be differentiated by: those of its law (the
    paper's family: b1 and b3, also at 0, where the Coulomb law is their limit), less
    the whole-number ones (no derivative)."""
    if params.friction is None:
        return ("b1", "b3")
    return tuple(p.name for p in params.law_spec.params if not p.integer)


def valid_wrt(params: OscillatorParams) -> tuple[str, ...]:
    """Every name ``wrt`` accepts for ``params``."""
    return CORE_WRT + law_wrt(params)


def check_wrt(params: OscillatorParams, wrt: object, start_stuck: bool) -> tuple[str, ...]:
    """``wrt`` as a tuple of names; ``TypeError``/``ValueError`` naming a bad one and the
    valid list (a whole-number law parameter with why; ``v0`` where the start is stuck:
    v is held at V there, so v0 is not free)."""
    if isinstance(wrt, str) or not isinstance(wrt, Sequence):
        raise TypeError(f"wrt must be a sequence of parameter names, {got(wrt)}")
    names = tuple(wrt)
    valid = valid_wrt(params)
    for name in names:
        if not isinstance(name, str):
            raise TypeError(f"wrt must hold parameter names (str), {got(name)}")
        if name not in valid:
            law = params.law_spec
            whole = [p.name for p in law.params if p.integer]
            if name in whole:
                raise ValueError(f"wrt: {name!r} of the {law.name} law takes whole values "
                                 f"only, so a run has no derivative by it; valid: {list(valid)}")
            raise ValueError(f"wrt: unknown parameter {name!r}; valid for this plant "
                             f"({law.name} law): {list(valid)}")
    if len(set(names)) != len(names):
        raise ValueError(f"wrt names a parameter twice: {list(names)}")
    if not names:
        raise ValueError("wrt is empty: name at least one parameter, or leave it out")
    if start_stuck and "v0" in names:
        raise ValueError("wrt: 'v0' has no derivative from a stuck start (mode 0 holds v at "
                         "V); start in slip, or differentiate by 'V'")
    return names


def seeds(params: OscillatorParams, wrt: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' seed records (``core.tangent.SEED_DTYPE``), one per name of ``wrt``, and
    the parameter row to run: the paper's family runs as the cubic law when a column is
    by b1 or b3, so that the Coulomb law (b1 = b3 = 0) has their derivatives too."""
    from .core.tangent import SEED_DTYPE

    seed = np.zeros(len(wrt), SEED_DTYPE)
    P = params.to_array()
    own = law_wrt(params)
    if params.friction is None and any(n in own for n in wrt):
        P[P_LAW] = friction.LAWS["cubic"].code
    slot = {"lam": "lam", "V": "V", "xfk": "xfk", "xfs": "xfs", "x0": "x0", "v0": "v0"}
    for j, name in enumerate(wrt):
        s = seed[j]
        if name in slot:
            s[slot[name]] = 1.0
        elif name == "eta":  # w1 = eta, w2 = nu eta
            s["w1"] = 1.0
            s["w2"] = params.nu
        elif name == "nu":
            s["w2"] = params.eta
        elif name == "u0":  # the tones that follow u0
            s["u1"] = 1.0 if params.u1 is None else 0.0
            s["u2"] = 1.0 if params.u2 is None else 0.0
        elif name in ("u1", "u2"):
            s[name] = 1.0
        else:  # the law's parameter block: b1, b3 in the paper's family, else the law's
            names = own if params.friction is None else params.law_spec.param_names
            s[f"law{names.index(name)}"] = 1.0
    return seed, P


@dataclass(frozen=True)
class TangentRun:
    """A recorded run with its tangent (:func:`record`): the state on the output grid,
    the switches, and their derivatives by each ``wrt`` column."""

    status: int
    state: np.ndarray
    stats: np.ndarray
    out_x: np.ndarray
    out_v: np.ndarray
    out_mode: np.ndarray
    ev_t: np.ndarray
    ev_kind: np.ndarray
    ev_x: np.ndarray
    dx_dp: np.ndarray
    dv_dp: np.ndarray
    ev_dt_dp: np.ndarray
    d_stats: np.ndarray
    singular: np.ndarray


def singular_points(flags: np.ndarray, n: int) -> np.ndarray:
    """The flagged points as a structured array (``t``, ``kind``, ``name``)."""
    from .core.tangent import FLAG_NAMES

    n = min(n, flags.shape[0])
    out = np.empty(n, SINGULAR_DTYPE)
    out["t"] = flags[:n, 0]
    out["kind"] = flags[:n, 1]
    out["name"] = [FLAG_NAMES[int(k)] for k in flags[:n, 1]]
    return out


#: Most points without a derivative a run notes (the tangent is NaN after the first).
MAX_FLAGS = 16


def record(P: np.ndarray, S0: np.ndarray, seed: np.ndarray, out_t: np.ndarray,
           settings: tuple[float, float, int],
           limits: tuple[tuple[float, float], int, float]) -> TangentRun:
    """Record a run from the state vector ``S0`` over the grid ``out_t`` with the event
    method, carrying one tangent column per seed. ``settings``: (rtol, atol,
    max_events); ``limits``: (the step budget, the first event buffer's size, grown by 4
    while full as ``simulate`` does, and the steps the call may take, for
    :func:`fricenv.calls.run_call`)."""
    from .core.recording import Recording
    from .core.tangent import N_TONE_ROWS, Tangent, law_rows_needed, record_tangent
    from .core.workspace import TAYLOR_MAX_ORDER
    from .layout import N_STATS

    budget, capacity, work_steps = limits
    n, k = out_t.shape[0], seed.shape[0]
    out_x, out_v, out_mode = np.empty(n), np.empty(n), np.empty(n)
    stats = np.empty(N_STATS)
    S = S0.copy()
    L = TAYLOR_MAX_ORDER + 2
    while True:
        rec = Recording(out_t, out_x, out_v, out_mode, np.empty(capacity),
                        np.empty(capacity, np.int8), np.empty(capacity),
                        np.zeros(2, np.int64))
        tan = Tangent(seed, np.empty((k, 2)), np.empty((n, k)), np.empty((n, k)),
                      np.full((capacity, k), np.nan), np.zeros((2, k)),
                      np.empty((MAX_FLAGS, 2)), np.zeros(1, np.int64),
                      np.empty((law_rows_needed(seed), L)), np.empty((N_TONE_ROWS + 1, L)),
                      np.empty((k, 2, L)))

        def go(work: np.ndarray, rec: Recording = rec, tan: Tangent = tan) -> int:
            from .core import reset_stats

            S[:] = S0
            reset_stats(stats)
            return record_tangent(P, S, settings, (rec, tan, stats), work)

        status = calls.run_call(go, lambda: calls.new_workspace(budget), work_steps)
        if status != STATUS_BUFFER_FULL:
            break
        capacity *= 4
    m = int(rec.counts[0])
    return TangentRun(status, S, stats, out_x, out_v, out_mode, rec.ev_t[:m].copy(),
                      rec.ev_kind[:m].copy(), rec.ev_x[:m].copy(), tan.out_dx, tan.out_dv,
                      tan.ev_dt[:m].copy(), tan.d_stats,
                      singular_points(tan.flags, int(tan.n_flags[0])))

