"""What the agents' commands share on the command line: the help formatter and the
stage lines of long runs."""

from __future__ import annotations

import argparse
import sys
import time


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's defaults in the help, except where there is nothing to show: a default
    of None (a required option, or one whose help names its own default)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or action.required or "(default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


class Stages:
    """One line per stage of a long command on stderr (``prog [12 s]: message``), so that
    a run of minutes says what it is doing from its first seconds; ``quiet``: no lines.

    The stages go to stderr, the results to stdout, so that redirecting the results keeps
    the progress on the terminal.
    """

    def __init__(self, prog: str, quiet: bool = False) -> None:
        self.prog = prog
        self.quiet = quiet
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"{self.prog} [{time.perf_counter() - self.t0:.0f} s]: {message}",
                  file=sys.stderr, flush=True)
