"""The benchmarks of ``fricenv bench``: solvers, sweep, env and compile.

Each module has ``main(argv, prog)``, returning the exit status (1 when a bound it checks
fails), and a module docstring saying what it measures and which bounds it checks. They
need only the installed package (the SciPy comparisons use
:mod:`fricenv.testing.scipy_reference` and need SciPy; ``env``'s PPO share needs
stable-baselines3), so they run from any working directory.

Progress goes through the ``fricenv`` logger at INFO (:func:`stage`): the ``fricenv``
command prints it on stderr, ``--quiet`` silences it, and a program that calls ``main``
itself sees it only where it configures logging. Results go to stdout.
"""

from __future__ import annotations

import logging

#: The package's logger; the ``fricenv`` command prints its INFO lines on stderr.
LOGGER = logging.getLogger("fricenv")

#: benchmark name -> what it measures (``fricenv bench --help`` lists them).
BENCHMARKS = {
    "solvers": "accuracy and cost of every method against RK4 and SciPy",
    "sweep": "regime-map cells against an event-driven SciPy loop, and full panels",
    "env": "environment step cost against Pendulum-v1, the vector env, PPO's share",
    "compile": "cold start: first calls in fresh processes, numba compile time by kernel",
}


def stage(text: str) -> None:
    """Announce a stage of a benchmark before it starts (silenced by ``--quiet``)."""
    LOGGER.info(text)


def show_progress() -> bool:
    """Whether progress bars should be drawn: when stage lines are shown."""
    return LOGGER.isEnabledFor(logging.INFO)
