"""The ``fricenv`` command: every job of the package behind one entry point.

``fricenv <command> --help`` describes each command. Each command's module lives here
(``fricenv.cli.atlas`` also serves ``python -m fricenv.atlas``), except the reproduction,
which has long lived as a module of its own (``fricenv.reproduce``) and keeps its parser;
this module only dispatches.

Other distributions add commands through the entry-point group :data:`PLUGIN_GROUP`
(``fricenv train`` and ``fricenv evaluate`` come from ``fricenv_agents`` this way, so that
the library imports nothing of the agents). A plugin is found from the installed metadata
alone and imported only when its command runs.

Before a command's first kernel call compiles (tens of seconds from an empty numba cache),
it prints one line to stderr saying so (:mod:`fricenv.compile_notice`; ``--quiet``, where a
command has it, silences it).
"""

from __future__ import annotations

import argparse
import functools
import importlib
import re
import sys
from collections.abc import Callable, Sequence
from importlib import metadata

#: command -> (module holding ``main(argv, prog)``, one-line summary). Modules are imported
#: only when their command runs, so ``fricenv --help`` never loads numba kernels or torch.
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("fricenv.cli.simulate", "time history of one plant: PNG plus npz or CSV"),
    "map": ("fricenv.cli.regime_map", "one regime-map panel over a u0 x nu grid (resumable)"),
    "atlas": ("fricenv.cli.atlas", "regime atlas over any parameter volume (Dask, Zarr)"),
    "reproduce": ("fricenv.reproduce", "the paper's Figs. 2-10 and a report of every claim"),
    "bench": ("fricenv.cli.bench", "run a benchmark: solvers, sweep, env or compile"),
    "warmup": ("fricenv.cli.warmup", "compile the kernels into numba's cache ahead of use"),
    "identify": ("fricenv.cli.identify", "which friction law produced a record: a report"),
    "design": ("fricenv.cli.design", "the two-tone excitation that reveals the friction best"),
}

#: Entry-point group of commands from other distributions: ``name = "module:function"``,
#: the function taking ``(argv, prog)`` like the built-in commands' ``main``; extras in
#: brackets name the requirements the command needs (checked before it is imported).
PLUGIN_GROUP = "fricenv.commands"
#: Summaries of the plugin commands this project ships (in ``fricenv_agents``), also shown
#: when they are not installed, with how to get them (:data:`PLUGIN_INSTALL`).
PLUGIN_SUMMARIES: dict[str, str] = {
    "train": "train a stick-slip suppression agent (stable-baselines3)",
    "evaluate": "evaluate trained agents against the baselines",
}
PLUGIN_INSTALL = 'pip install "fricenv[rl]" (in a checkout: pip install -e ".[rl]")'


@functools.cache
def plugins() -> dict[str, metadata.EntryPoint]:
    """Plugin commands of the installed distributions, by name (none imported). A name
    that is also a built-in command is ignored: the built-in wins."""
    found: dict[str, metadata.EntryPoint] = {}
    for ep in metadata.entry_points(group=PLUGIN_GROUP):
        if ep.name not in COMMANDS:
            found.setdefault(ep.name, ep)
    return found


def missing_requirements(ep: metadata.EntryPoint) -> list[str]:
    """The distributions that ``ep``'s extras require and that are not installed."""
    dist = ep.dist
    if not ep.extras or dist is None:
        return []
    missing = []
    for req in dist.requires or []:
        spec, _, marker = req.partition(";")
        if not any(re.search(rf"extra\s*==\s*['\"]{re.escape(x)}['\"]", marker)
                   for x in ep.extras):
            continue
        name = re.split(r"[\s<>=!~\[(;@]", spec.strip(), maxsplit=1)[0]
        try:
            metadata.distribution(name)
        except metadata.PackageNotFoundError:
            missing.append(name)
    return missing


def _unavailable(name: str) -> str | None:
    """Why plugin command ``name`` cannot run (``None`` if it can)."""
    ep = plugins().get(name)
    if ep is None:
        return "not installed"
    missing = missing_requirements(ep)
    return f"needs {', '.join(missing)}" if missing else None


def _listing() -> tuple[dict[str, str], list[str]]:
    """Every command's line of ``fricenv --help`` (built-ins, then plugins, installed or
    not), and the names of those that cannot run."""
    lines = {name: summary for name, (_, summary) in COMMANDS.items()}
    unavailable = []
    for name in [*PLUGIN_SUMMARIES, *(n for n in plugins() if n not in PLUGIN_SUMMARIES)]:
        ep = plugins().get(name)
        summary = PLUGIN_SUMMARIES.get(name) or (
            f"from {ep.dist.name}" if ep is not None and ep.dist is not None else "plugin")
        why = _unavailable(name)
        lines[name] = summary if why is None else f"{summary} [{why}]"
        if why is not None:
            unavailable.append(name)
    return lines, unavailable


def _parser() -> argparse.ArgumentParser:
    names, unavailable = _listing()
    width = max(map(len, names))
    listing = "\n".join(f"  {name:<{width}}  {summary}" for name, summary in names.items())
    if unavailable:
        listing += f"\n\n{', '.join(unavailable)}: {PLUGIN_INSTALL}"
    p = argparse.ArgumentParser(
        prog="fricenv", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Exact simulation of a two-tone forced dry-friction oscillator: "
                    "time histories, regime maps, the paper's figures, RL agents.",
        epilog=f"commands:\n{listing}\n\n'fricenv <command> --help' shows a command's options."
               "\n\nexample:\n  fricenv simulate --case 5a --out out/fig5a")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument("command", choices=list(names), metavar="command",
                   help="one of: " + ", ".join(names))
    return p


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("fricenv")
    except PackageNotFoundError:  # a source tree on sys.path, not installed
        return "(not installed)"


def command_main(name: str) -> Callable[..., object]:
    """The ``main(argv, prog)`` of command ``name``, a built-in or a plugin (imported
    now); ``KeyError`` for a name that is neither."""
    if name in COMMANDS:
        return importlib.import_module(COMMANDS[name][0]).main
    main: Callable[..., object] = plugins()[name].load()
    return main


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``fricenv`` with ``argv`` (default: the process's arguments); returns the exit
    status. Usage errors exit with status 2 and a message naming the bad value."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    if not argv or argv[0] not in COMMANDS and argv[0] not in plugins():
        parser.parse_args(argv[:1] or ["--help"])  # --help, --version, or a clear error
        if argv[0] in PLUGIN_SUMMARIES:  # (a valid choice that is not installed)
            parser.error(f"fricenv {argv[0]} is not installed: {PLUGIN_INSTALL}")
        return 2
    why = None if argv[0] in COMMANDS else _unavailable(argv[0])
    if why is not None:
        parser.error(f"fricenv {argv[0]} {why}: {PLUGIN_INSTALL}")
    from fricenv import compile_notice
    from fricenv.cli import _notice
    from fricenv.interrupts import interrupts_redelivered

    try:
        with (interrupts_redelivered(), _notice.log_to_stderr(quiet="--quiet" in argv[1:]),
              compile_notice.in_command()):
            _notice.announce_command(argv[0], argv[1:])
            status = command_main(argv[0])(argv[1:], prog=f"fricenv {argv[0]}")
    except KeyboardInterrupt as e:  # (a command that reports its own exits 130 itself)
        from fricenv.cli._args import interrupted

        return interrupted(f"fricenv {argv[0]}", e)
    return status if isinstance(status, int) else 0


if __name__ == "__main__":
    sys.exit(main())
