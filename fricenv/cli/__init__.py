"""The ``fricenv`` command: every job of the package behind one entry point.

``fricenv <command> --help`` describes each command. Commands that have long lived as
modules of their own (``fricenv.reproduce``, ``agents.train``, ``agents.evaluate``,
``fricenv.atlas``) keep their own parsers; this module only dispatches, so
``python -m agents.train`` and ``fricenv train`` accept the same options.

Before a command's first kernel call compiles (tens of seconds from an empty numba cache),
it prints one line to stderr saying so (:mod:`fricenv.compile_notice`; ``--quiet``, where a
command has it, silences it).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence

#: command -> (module holding ``main(argv, prog)``, one-line summary). Modules are imported
#: only when their command runs, so ``fricenv --help`` never loads numba kernels or torch.
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("fricenv.cli.simulate", "time history of one plant: PNG plus npz or CSV"),
    "map": ("fricenv.cli.regime_map", "one regime-map panel over a u0 x nu grid (resumable)"),
    "atlas": ("fricenv.cli.atlas", "regime atlas over any parameter volume (Dask, Zarr)"),
    "reproduce": ("fricenv.reproduce", "the paper's Figs. 2-10 and a report of every claim"),
    "train": ("agents.train", "train a stick-slip suppression agent (stable-baselines3)"),
    "evaluate": ("agents.evaluate", "evaluate trained agents against the baselines"),
    "bench": ("fricenv.cli.bench", "run a benchmark: solvers, sweep, env or compile"),
    "warmup": ("fricenv.cli.warmup", "compile the kernels into numba's cache ahead of use"),
}


def _parser() -> argparse.ArgumentParser:
    width = max(map(len, COMMANDS))
    listing = "\n".join(f"  {name:<{width}}  {summary}" for name, (_, summary)
                        in COMMANDS.items())
    p = argparse.ArgumentParser(
        prog="fricenv", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Exact simulation of a two-tone forced dry-friction oscillator: "
                    "time histories, regime maps, the paper's figures, RL agents.",
        epilog=f"commands:\n{listing}\n\n'fricenv <command> --help' shows a command's options."
               "\n\nexample:\n  fricenv simulate --case 5a --out out/fig5a")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument("command", choices=list(COMMANDS), metavar="command",
                   help="one of: " + ", ".join(COMMANDS))
    return p


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fricenv")
    except PackageNotFoundError:  # a source tree on sys.path, not installed
        return "(not installed)"


def command_main(name: str) -> Callable[..., object]:
    """The ``main(argv, prog)`` of command ``name`` (``KeyError`` for an unknown one)."""
    module = importlib.import_module(COMMANDS[name][0])
    return module.main


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``fricenv`` with ``argv`` (default: the process's arguments); returns the exit
    status. Usage errors exit with status 2 and a message naming the bad value."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    if not argv or argv[0] not in COMMANDS:
        parser.parse_args(argv[:1] or ["--help"])  # --help, --version, or a clear error
        return 2
    from fricenv.cli import _notice

    with _notice.log_to_stderr(quiet="--quiet" in argv[1:]):
        _notice.announce_command(argv[0], argv[1:])
        status = command_main(argv[0])(argv[1:], prog=f"fricenv {argv[0]}")
    return status if isinstance(status, int) else 0


if __name__ == "__main__":
    sys.exit(main())
