"""The environments' entry kernels for each core method, and which one an environment runs.

Numba compiles a kernel with everything it calls. The step kernels that take the core's
method at run time (``kernels.step_single``, ``batch.step_batch``, ...) therefore compile
the closed form, the Taylor steps and the Rosenbrock steps, whatever the plant. An
environment instead runs the kernels of the one method its plants need (:func:`steppers_for`):
a Coulomb scene compiles no Taylor or Rosenbrock code, and its first step comes that much
sooner from an empty cache. The bodies are written once (``*_with``); each set below only
names the core's entry kernel it is built on.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from fricenv.core import (
    advance_event,
    advance_event_ws,
    advance_exact,
    advance_exact_ws,
    always_conditioned,
)
from fricenv.envs import batch
from fricenv.envs import kernels as K
from fricenv.friction import closed_form_rows, polynomial_laws_in
from fricenv.jit import kernel
from fricenv.layout import METHOD_EVENT, METHOD_EXACT
from fricenv.params import P_LAM, P_LAW


@kernel
def step_single_exact(P, S, ctrl, cfg, a, stats, obs, res, work) -> int:
    return K.step_single_with(advance_exact_ws, P, S, ctrl, cfg, a, stats, obs, res, work)


@kernel
def step_single_event(P, S, ctrl, cfg, a, stats, obs, res, work) -> int:
    return K.step_single_with(advance_event_ws, P, S, ctrl, cfg, a, stats, obs, res, work)


@kernel
def _step_range_exact(lo, hi, table, cfg, A, obs, res, flags, counters, draws, bounds,
                      max_steps, mode) -> None:
    batch.step_range_with(advance_exact_ws, lo, hi, table, cfg, A, obs, res, flags, counters,
                          draws, bounds, max_steps, mode)


@kernel
def _step_range_event(lo, hi, table, cfg, A, obs, res, flags, counters, draws, bounds,
                      max_steps, mode) -> None:
    batch.step_range_with(advance_event_ws, lo, hi, table, cfg, A, obs, res, flags, counters,
                          draws, bounds, max_steps, mode)


@kernel
def step_batch_exact(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
    return batch.step_batch_with(_step_range_exact, table, cfg, A, obs, res, flags, counters,
                                 draws, bounds, ivars)


@kernel
def step_batch_event(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
    return batch.step_batch_with(_step_range_event, table, cfg, A, obs, res, flags, counters,
                                 draws, bounds, ivars)


@kernel(parallel=True)
def step_batch_parallel_exact(table, cfg, A, obs, res, flags, counters, draws, bounds,
                              ivars) -> int:
    return batch.step_batch_parallel_with(advance_exact_ws, table, cfg, A, obs, res, flags,
                                          counters, draws, bounds, ivars)


@kernel(parallel=True)
def step_batch_parallel_event(table, cfg, A, obs, res, flags, counters, draws, bounds,
                              ivars) -> int:
    return batch.step_batch_parallel_with(advance_event_ws, table, cfg, A, obs, res, flags,
                                          counters, draws, bounds, ivars)


@kernel(allocates=True)
def sample_interval_exact(P, S, ctrl, cfg, a, stats, t_out, v_out, stick_out) -> int:
    return K.sample_interval_with(advance_exact, P, S, ctrl, cfg, a, stats, t_out, v_out,
                                  stick_out)


@kernel(allocates=True)
def sample_interval_event(P, S, ctrl, cfg, a, stats, t_out, v_out, stick_out) -> int:
    return K.sample_interval_with(advance_event, P, S, ctrl, cfg, a, stats, t_out, v_out,
                                  stick_out)


class Steppers(NamedTuple):
    """One set of an environment's entry kernels (the arguments of ``kernels.step_single``,
    ``batch.step_batch``, ``batch.step_batch_parallel``, ``kernels.sample_interval``)."""

    name: str
    step_single: Callable[..., Any]
    step_batch: Callable[..., Any]
    step_batch_parallel: Callable[..., Any]
    sample_interval: Callable[..., Any]


#: The closed form alone: every plant Coulomb and conditioned (``steppers_for``).
EXACT = Steppers("exact", step_single_exact, step_batch_exact, step_batch_parallel_exact,
                 sample_interval_exact)
#: The event method alone.
EVENT = Steppers("event", step_single_event, step_batch_event, step_batch_parallel_event,
                 sample_interval_event)
#: The method chosen per plant and step at run time (``kernels._method``), the closed form
#: falling back to the event method near resonance: compiles both.
ANY = Steppers("any", K.step_single, batch.step_batch, batch.step_batch_parallel,
               K.sample_interval)


def steppers_for(method: int, lam_min: float, coulomb: bool, friction: bool) -> Steppers:
    """The entry kernels for plants that an environment may meet.

    ``method``: the configured core method (``kernels.METHOD_AUTO``: by the plant's law);
    ``lam_min``: the least damping of any such plant; ``coulomb`` / ``friction``: whether
    some of them follow the Coulomb law / another law. Every set gives the same results
    where it applies; the narrowest that covers the plants compiles the least.
    """
    if method == METHOD_EVENT or (method == K.METHOD_AUTO and not coulomb):
        return EVENT
    if (method in (METHOD_EXACT, K.METHOD_AUTO) and not friction
            and always_conditioned(lam_min)):
        return EXACT
    return ANY


def steppers_for_plants(method: int, P_rows: np.ndarray, lo: np.ndarray | None = None,
                        hi: np.ndarray | None = None) -> Steppers:
    """``steppers_for`` the plants of the rows of ``P_rows`` (layout ``params.P_*``) and, if
    given, those drawn from the draw bounds ``lo``, ``hi`` (layout ``tables.D_*``)."""
    P_rows = np.atleast_2d(np.asarray(P_rows, dtype=float))
    law = ~closed_form_rows(P_rows[:, P_LAW])
    coulomb = bool((~law).any())
    friction = bool(law.any())
    lam_min = float(P_rows[:, P_LAM].min()) if P_rows.size else np.inf
    if lo is not None and hi is not None:
        drawn = polynomial_laws_in((lo[K.D_B1], hi[K.D_B1]), (lo[K.D_B3], hi[K.D_B3]))
        coulomb = coulomb or "coulomb" in drawn
        friction = friction or "cubic" in drawn
        lam_min = min(lam_min, float(lo[K.D_LAM]))
    return steppers_for(method, lam_min, coulomb, friction)
