"""Entry kernels: the stats-only ``advance`` and the recording ``record``, per method; and
:func:`partial_kernel`, which builds a method's kernels from a body written once.

Numba compiles a kernel together with everything it calls, whatever branch runs. So each
method has its own entry kernels (``advance_exact``, ``advance_event``, ``record_exact``,
...), and a workload compiles only its method's code: a Coulomb run never compiles the
Taylor or Rosenbrock steps. ``advance``, ``advance_ws``, ``advance_any_ws`` and ``record``
take the method at run time and compile both. :func:`kernels_for` picks a plant's entry
kernels in Python.

The per-method kernels take how the call runs as one :class:`Solver` record (method,
tolerances, event cap); ``advance`` and ``advance_ws`` keep their scalar arguments, as the
kernels that callers outside the package use. The kernels called from Python take their
records as plain tuples too (``tuple(solver)``): numba types a plain tuple of arrays from
its fingerprint, a named one field by field in Python, which made a short call several
microseconds longer.

The exact method cannot run a tone too close to resonance (see CLOSED_FORM_MAX_GAIN): its
kernels then return ``_STATUS_NEAR_RESONANCE`` having changed nothing, and the
method-taking kernels run the event method instead. :func:`method_for` makes that choice
before the call, for the per-method kernels.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from ..jit import kernel
from ..layout import METHOD_EVENT, METHOD_EXACT
from .constants import _STATUS_NEAR_RESONANCE, LAM_CONDITIONED
from .context import closed_form_conditioned
from .event import _run_event
from .exact import _run_exact
from .recording import Recording, stats_only


class Solver(NamedTuple):
    """How a call runs: ``method`` (METHOD_EXACT or METHOD_EVENT; read only by the kernels
    that take the method at run time), the event method's ``rtol`` and ``atol``, and
    ``max_events``, the switches allowed in the call (STATUS_EVENT_CAP beyond)."""

    method: int
    rtol: float
    atol: float
    max_events: int


@kernel
def advance_exact_ws(P, S, t_span, stats, solver, work):
    """``advance_ws`` with the closed form alone (``solver.method``, ``rtol`` and ``atol``
    are not read): _STATUS_NEAR_RESONANCE, nothing changed, if a tone of P is too close to
    resonance for it (see :func:`method_for`)."""
    return _run_exact(P, S, t_span, stats, solver.max_events, stats_only(work), work)


@kernel
def advance_event_ws(P, S, t_span, stats, solver, work):
    """``advance_ws`` with the event method alone (``solver.method`` is not read)."""
    return _run_event(P, S, t_span, stats, solver.max_events, solver.rtol, solver.atol,
                      stats_only(work), work)


@kernel
def advance_any_ws(P, S, t_span, stats, solver, work):
    """``advance_ws`` with the run's settings as one :class:`Solver` (the per-method
    kernels' arguments, so that a body written once takes any of the three)."""
    if solver.method == METHOD_EXACT:
        status = advance_exact_ws(P, S, t_span, stats, solver, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return advance_event_ws(P, S, t_span, stats, solver, work)


@kernel
def advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance`` with a caller-owned workspace (see ``new_workspace``).

    Reusing one workspace per plant across calls spares the allocation and, for the
    closed-form method, the transition constants and the tone phases' cos/sin, which is
    most of the cost of a short call such as one control interval of an environment.
    """
    return advance_any_ws(P, S, t_span, stats, Solver(method, rtol, atol, max_events), work)


@kernel(allocates=True, nogil=True)
def advance_exact(P, S, t_span, stats, solver, work):
    """``advance`` with the closed form alone (see ``advance_exact_ws``)."""
    return advance_exact_ws(P, S, t_span, stats, Solver(*solver), work)


@kernel(allocates=True, nogil=True)
def advance_event(P, S, t_span, stats, solver, work):
    """``advance`` with the event method alone."""
    return advance_event_ws(P, S, t_span, stats, Solver(*solver), work)


@kernel(allocates=True, nogil=True)
def advance(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """Advance the state ``S`` in place by ``t_span``, accumulating ``stats``; no trajectory.

    ``method`` is METHOD_EXACT (Coulomb law only; the caller checks; a call with a tone
    too close to resonance runs the event method, see CLOSED_FORM_MAX_GAIN) or
    METHOD_EVENT.
    Tone phases are carried in ``S``, so P's amplitudes and frequencies may change between
    calls without a jump in the force. Returns a STATUS_* code; at most ``max_events``
    switches are allowed in the call (STATUS_EVENT_CAP beyond), and at most the step
    budget of the workspace (STATUS_STEP_BUDGET beyond, see MAX_STEPS_PER_TAU). ``work``:
    a fresh workspace (``new_workspace``) to run in, whose budget slots bound the call. The
    GIL is released while it runs.
    """
    return advance_any_ws(P, S, t_span, stats, Solver(method, rtol, atol, max_events), work)


@kernel(allocates=True, nogil=True)
def record_exact(P, S, stats, solver, rec, work):
    """``record`` with the closed form alone (see ``advance_exact_ws``)."""
    named = Recording(*rec)
    t_span = named.out_t[named.out_t.shape[0] - 1] - named.out_t[0]
    return _run_exact(P, S, t_span, stats, Solver(*solver).max_events, named, work)


@kernel(allocates=True, nogil=True)
def record_event(P, S, stats, solver, rec, work):
    """``record`` with the event method alone."""
    named = Recording(*rec)
    run = Solver(*solver)
    t_span = named.out_t[named.out_t.shape[0] - 1] - named.out_t[0]
    return _run_event(P, S, t_span, stats, run.max_events, run.rtol, run.atol, named, work)


@kernel(allocates=True, nogil=True)
def record(P, S, stats, solver, rec, work):
    """Like ``advance`` over [out_t[0], out_t[-1]] of the :class:`Recording` ``rec``,
    recording the state at ``rec.out_t`` and the events (time, kind, x); ``rec.counts``
    returns (events recorded, outputs written). ``solver``: the method (chosen at run time,
    as in ``advance``) and its settings; ``work`` as in ``advance``. Both records may come
    as plain tuples (see the module docstring)."""
    named = Recording(*rec)
    run = Solver(*solver)
    t_span = named.out_t[named.out_t.shape[0] - 1] - named.out_t[0]
    if run.method == METHOD_EXACT:
        status = _run_exact(P, S, t_span, stats, run.max_events, named, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return _run_event(P, S, t_span, stats, run.max_events, run.rtol, run.atol, named, work)


def method_for(method: int, P: np.ndarray) -> int:
    """The method that runs plant ``P`` when ``method`` is asked for: METHOD_EVENT for
    METHOD_EXACT where a tone is too close to resonance for the closed form (what
    ``advance`` does inside), else ``method``."""
    if method == METHOD_EXACT and not closed_form_conditioned(P):
        return METHOD_EVENT
    return method


def always_conditioned(lam_min: float) -> bool:
    """Whether the closed form runs every plant whose damping is at least ``lam_min``,
    whatever its tones (see LAM_CONDITIONED): a workload whose plants all qualify never
    needs the event method's fallback."""
    return lam_min >= LAM_CONDITIONED


class EntryKernels(NamedTuple):
    """A method's entry kernels: ``advance_ws`` and ``advance`` take ``(P, S, t_span,
    stats, solver, work)``, ``record`` takes ``(P, S, stats, solver, rec, work)``."""

    advance_ws: Callable[..., Any]
    advance: Callable[..., Any]
    record: Callable[..., Any]


#: Each method's entry kernels; METHOD_EXACT's need a conditioned plant (``method_for``).
ENTRY_KERNELS = {
    METHOD_EXACT: EntryKernels(advance_exact_ws, advance_exact, record_exact),
    METHOD_EVENT: EntryKernels(advance_event_ws, advance_event, record_event),
}


def kernels_for(method: int, P: np.ndarray) -> EntryKernels:
    """The entry kernels that run plant ``P`` by ``method`` (METHOD_EXACT or METHOD_EVENT)
    and compile nothing else."""
    return ENTRY_KERNELS[method_for(method, P)]


#: The kernels :func:`partial_kernel` made in this process, by name.
_PARTIALS: dict[str, tuple[Any, Any, Any]] = {}


def partial_kernel(body: Any, first: Any, name: str, **options: Any) -> Any:
    """The kernel ``name(*args) = body(first, *args)``: a generic body bound to the kernel
    it takes first, compiled and cached as a kernel of its own; ``options`` are
    :func:`fricenv.jit.kernel`'s (``parallel``, ``allocates``, ``nogil``).

    A body written once over the kernel it runs (``takes_kernels``: the core's entry kernel
    of a method, a cell's run) needs, per method, a named kernel that passes that kernel:
    numba's cache refuses a function holding a kernel it was passed at run time, and one
    holding it in a closure is keyed on a pickle of the kernel that changes from process to
    process. So the caller is written here, from the body's own parameters, with the body
    and the kernel as globals (beside the body module's); it is named ``name`` (the name of
    its cache files) and lives in the body's file and module, so that the package's cache
    and the compile notice treat it as any kernel there. The same arguments give the same
    kernel (one compile per process at most); another body or kernel under a name already
    made is refused, as the two would share their cache files.
    """
    made = _PARTIALS.get(name)
    if made is not None:
        if made[:2] != (body, first):
            raise ValueError(f"partial_kernel {name!r} already binds another body or kernel")
        return made[2]
    py_func = body.py_func
    params = ", ".join(list(inspect.signature(py_func).parameters)[1:])
    source = f"def {name}({params}):\n    return _partial_body(_partial_first, {params})\n"
    # (the body's module globals too: numba's parallel lowering names the loop's types
    # there, as Python source)
    namespace = {**py_func.__globals__, "_partial_body": body, "_partial_first": first}
    exec(compile(source, py_func.__code__.co_filename, "exec"), namespace)
    fn = namespace[name]
    fn.__module__ = py_func.__module__
    fn.__qualname__ = name
    fn.__doc__ = f"``{body.__name__}`` by ``{first.__name__}`` (made by ``partial_kernel``)."
    dispatcher = kernel(fn, **options)
    _PARTIALS[name] = (body, first, dispatcher)
    return dispatcher


def partial_kernels() -> dict[str, Any]:
    """The kernels :func:`partial_kernel` made in this process, by name."""
    return {name: made[2] for name, made in _PARTIALS.items()}
