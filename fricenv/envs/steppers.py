"""The environments' entry kernels for each core method, and which one an environment runs.

Numba compiles a kernel with everything it calls. Step kernels that took the core's method
at run time would compile the closed form, the Taylor steps and the Rosenbrock steps,
whatever the plant. An environment instead runs the kernels of the one method its plants
need (:func:`steppers_for`): a Coulomb scene compiles no Taylor or Rosenbrock code, and its
first step comes that much sooner from an empty cache. The bodies are written once
(``*_with`` in :mod:`fricenv.envs.kernels` and :mod:`fricenv.envs.batch`);
:func:`steppers_on` builds a set from the core's entry kernel of a method.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from fricenv.core import (
    advance_any_ws,
    advance_event_ws,
    advance_exact_ws,
    always_conditioned,
    partial_kernel,
)
from fricenv.envs import batch
from fricenv.envs import kernels as K
from fricenv.friction import closed_form_rows, polynomial_laws_in
from fricenv.layout import METHOD_EVENT, METHOD_EXACT
from fricenv.params import P_LAM, P_LAW


class Steppers(NamedTuple):
    """One set of an environment's entry kernels, all built on the core's entry kernel
    ``advance_ws`` (``(P, S, t_span, stats, solver, work)``), which batch rollouts build
    theirs on too. Arguments: ``step_single`` and ``step_batch_parallel`` those of
    ``kernels.step_single_with`` and ``batch.step_batch_parallel_with``, ``step_batch``
    those of ``batch.step_batch_with``, ``sample_interval`` those of
    ``kernels.sample_interval_with``, each but the first."""

    name: str
    step_single: Callable[..., Any]
    step_batch: Callable[..., Any]
    step_batch_parallel: Callable[..., Any]
    sample_interval: Callable[..., Any]
    advance_ws: Callable[..., Any]


def steppers_on(advance_ws: Any, name: str) -> Steppers:
    """The entry kernels of the environments built on the core's entry kernel
    ``advance_ws``, named after ``name`` (``step_single_exact``, ...): both batch steps
    call one plant-range kernel of their own (``_step_range_<name>``), the serial one over
    every plant, the parallel one per share of ``batch.TASKS_PER_THREAD`` per thread."""
    step_range = partial_kernel(batch.step_range_with, advance_ws, f"_step_range_{name}")
    return Steppers(
        name,
        partial_kernel(K.step_single_with, advance_ws, f"step_single_{name}"),
        partial_kernel(batch.step_batch_with, step_range, f"step_batch_{name}"),
        partial_kernel(batch.step_batch_parallel_with, step_range,
                       f"step_batch_parallel_{name}", parallel=True),
        partial_kernel(K.sample_interval_with, advance_ws, f"sample_interval_{name}",
                       allocates=True),
        advance_ws)


#: The closed form alone: every plant Coulomb and conditioned (``steppers_for``).
EXACT = steppers_on(advance_exact_ws, "exact")
#: The event method alone.
EVENT = steppers_on(advance_event_ws, "event")
#: The method chosen per plant and step at run time (``kernels._method``), the closed form
#: falling back to the event method near resonance: compiles both.
ANY = steppers_on(advance_any_ws, "any")


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
