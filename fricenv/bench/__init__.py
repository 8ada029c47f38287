"""The benchmarks of ``fricenv bench``: solvers, sweep, env, compile and derivatives.

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
    "derivatives": "cost and accuracy of runs with forward sensitivities (wrt=)",
}


def stage(text: str) -> None:
    """Announce a stage of a benchmark before it starts (silenced by ``--quiet``)."""
    LOGGER.info(text)


def show_progress() -> bool:
    """Whether progress bars should be drawn: when stage lines are shown."""
    return LOGGER.isEnabledFor(logging.INFO)


#: The option of the benchmarks that check bounds: report the numbers, judge nothing.
REPORT_ONLY_HELP = ("report the measurements and which bounds they miss, but exit 0: for "
                    "a busy machine, where timing bounds say more about the load than the "
                    "code")


def machine_load() -> str:
    """The machine's load as the verdict states it: the load averages over 1, 5 and 15
    minutes (``os.getloadavg``, where the system has it) and the number of cores."""
    import os

    cores = os.cpu_count() or 1
    try:
        one, five, fifteen = os.getloadavg()
    except (AttributeError, OSError):  # (Windows)
        return f"load average unavailable, {cores} cores"
    return (f"load average {one:.2f}, {five:.2f}, {fifteen:.2f} over 1, 5, 15 min on "
            f"{cores} cores")


def verdict(failures: list[str], report_only: bool) -> int:
    """Print the verdict of a benchmark that checks bounds and return its exit status.

    ``failures``: one line per bound that does not hold, naming the bound and the value
    measured (e.g. ``"bound 2 (single / vector >= 20), fricenv/StickSlip-v0: measured
    14.31"``). The verdict names each, with the machine's load at the end of the run, since
    a loaded machine fails timing bounds that an idle one meets. ``report_only``: the same
    lines, as a report, and status 0."""
    load = machine_load()
    if not failures:
        print(f"PASS: every bound holds ({load})")
        return 0
    head = ("NOT JUDGED (--report-only): these bounds are missed" if report_only
            else "FAIL: these bounds do not hold")
    print(f"{head}, with the machine at {load}:")
    for line in failures:
        print(f"  - {line}")
    if report_only:
        return 0
    print("  Timing bounds depend on the load: rerun on an idle machine, or pass "
          "--report-only to report without judging.")
    return 1
