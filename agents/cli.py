"""The argparse formatter of the agents' commands."""

from __future__ import annotations

import argparse


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's defaults in the help, except where there is nothing to show: a default
    of None (a required option, or one whose help names its own default)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or action.required or "(default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)
