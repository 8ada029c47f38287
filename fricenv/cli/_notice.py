"""The ``fricenv`` command's compile notice: one line on stderr before kernels compile.

The commands under ``fricenv.cli`` announce their own workloads once their arguments have
parsed (:func:`announce`). The commands whose modules keep parsers of their own
(``reproduce``, ``train``, ``evaluate``) are announced here, before they start, from the
few options that decide their workloads (:data:`COMMAND_NEEDS`); their own parser still
judges every argument. Nothing here compiles or loads a kernel, and a check that fails
for any reason stays silent rather than stopping the command.

The long commands also log a line as each stage starts (:func:`stage`, the same logger):
:func:`log_to_stderr` prints both kinds on stderr, and ``--quiet`` silences both.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import NoReturn

#: The logger every notice goes through (the package adds only a ``NullHandler``).
LOGGER = logging.getLogger("fricenv")

Needs = list[tuple[str, str]]


@contextlib.contextmanager
def log_to_stderr(quiet: bool = False) -> Iterator[None]:
    """Print the ``fricenv`` logger's INFO lines (the compile notice) to stderr for the
    duration of a command; ``quiet``: warnings only. Not passed on to the root logger (a
    command that configures logging would print them twice). Restores the logger
    afterwards."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("fricenv: %(message)s"))
    level, propagate = LOGGER.level, LOGGER.propagate
    LOGGER.addHandler(handler)
    LOGGER.setLevel(logging.WARNING if quiet else logging.INFO)
    LOGGER.propagate = False
    try:
        yield
    finally:
        LOGGER.removeHandler(handler)
        LOGGER.setLevel(level)
        LOGGER.propagate = propagate


def stage(text: str) -> None:
    """A progress line of a command's stage, before the stage starts: on stderr under the
    ``fricenv`` command (silenced by ``--quiet``), on the ``fricenv`` logger otherwise."""
    LOGGER.info(text)


def announce(needs: Iterable[tuple[str, str]] | Callable[[], Iterable[tuple[str, str]]],
             ) -> bool:
    """Log the compile notice for ``(workload, method)`` pairs (or for what a function
    returns, so that working them out is covered too); whether a notice was logged. Any
    failure is logged at DEBUG and ignored: the notice never stops a command."""
    try:
        from fricenv import compile_notice

        return compile_notice.announce(needs() if callable(needs) else needs)
    except Exception as e:  # (a renamed kernel, another numba: no notice, no failure)
        LOGGER.debug("compile check failed: %r", e)
        return False


class _Sniff(argparse.ArgumentParser):
    """A parser that reads a few options and ignores the rest; raises instead of
    printing and exiting, so that the command's own parser reports bad arguments."""

    def error(self, message: str) -> NoReturn:
        raise ValueError(message)


def _sniff(argv: Sequence[str], *options: tuple[str, dict]) -> argparse.Namespace:
    p = _Sniff(add_help=False)
    for flag, kwargs in options:
        p.add_argument(flag, **kwargs)
    return p.parse_known_args(list(argv))[0]


def _law_needs(workload: str, laws: Iterable[str]) -> Needs:
    from fricenv.compile_notice import method_for_law

    return [(workload, method_for_law(law)) for law in laws]


def _scene_needs(workloads: Sequence[str], scenes: Iterable[str]) -> Needs:
    from fricenv.compile_notice import method_for_scene

    return [(w, method_for_scene(s)) for s in scenes for w in workloads]


def reproduce_needs(argv: Sequence[str]) -> Needs:
    """``fricenv reproduce``: the amplitude figures (2, 3) sweep Coulomb cells, the time
    histories (4-7) simulate Coulomb plants and sweep their cells, the maps (8-10) sweep
    each figure's law."""
    from fricenv.reproduce.common import MAP_FIGURES

    only = {s.strip() for s in _sniff(argv, ("--only", {"default": "2,3,4-7,8-10"}))
            .only.split(",")}
    needs: Needs = []
    if only & {"2", "3", "4-7"}:
        needs += _law_needs("sweep", ["coulomb"])
    if "4-7" in only:
        needs += _law_needs("simulate", ["coulomb"])
    if "8-10" in only:
        needs += _law_needs("sweep", [law for law, _ in MAP_FIGURES.values()])
    return needs


def train_needs(argv: Sequence[str]) -> Needs:
    """``fricenv train``: the scene's vector environment (``StickSlipSB3VecEnv``)."""
    scene = _sniff(argv, ("--scene", {})).scene
    return _scene_needs(["vector_env"], [scene]) if scene else []


def evaluate_needs(argv: Sequence[str]) -> Needs:
    """``fricenv evaluate``: each scene's vector environment (the evaluation episodes) and
    single environment (the time histories)."""
    from fricenv.envs import ENV_IDS

    scenes = _sniff(argv, ("--scene", {"nargs": "+"})).scene or list(ENV_IDS.values())
    return _scene_needs(["vector_env", "env"], scenes)


#: command -> its ``(workload, method)`` pairs from its arguments, for the commands whose
#: modules live outside ``fricenv.cli``.
COMMAND_NEEDS: dict[str, Callable[[Sequence[str]], Needs]] = {
    "reproduce": reproduce_needs,
    "train": train_needs,
    "evaluate": evaluate_needs,
}


def announce_command(command: str, argv: Sequence[str]) -> bool:
    """The notice for ``command`` of :data:`COMMAND_NEEDS` run with ``argv`` (nothing for
    ``--help`` or another command)."""
    needs = COMMAND_NEEDS.get(command)
    if needs is None or "-h" in argv or "--help" in argv:
        return False
    return announce(lambda: needs(argv))
