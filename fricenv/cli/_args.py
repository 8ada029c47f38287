"""What the ``fricenv`` commands share: the help formatter, parameter assignments and
grid specs.

Each parser raises ``argparse.ArgumentTypeError`` with the offending text, so argparse
prints ``error: argument --set: ...`` and exits with status 2 before any work starts.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fricenv.interrupts import interrupted as interrupted
from fricenv.params import FRICTION_LAWS, PAPER_CASES, OscillatorParams


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """The help of every ``fricenv`` command: the description and the epilog (examples)
    as written, and each option's default appended once, where it says something.

    argparse's ``ArgumentDefaultsHelpFormatter`` appends ``(default: ...)`` to every
    option, also after a help text that already names the default, and shows ``None`` and
    ``False`` (an option left out, a flag). Here the default is appended only when the
    help does not mention one and it is a value: not ``None``, ``False`` or empty. A list
    shows as its items, as they are typed on the command line.
    """

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        """A one-paragraph description wrapped to the terminal; a text of several lines
        (the examples) as written."""
        if "\n" in text:
            return super()._fill_text(text, width, indent)
        return argparse.HelpFormatter._fill_text(self, text, width, indent)

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (not action.option_strings or "(default" in text or "%(default)" in text
                or default is None or default is False or default is argparse.SUPPRESS
                or (isinstance(default, list | tuple) and not default)):
            return action.help
        shown = " ".join(map(str, default)) if isinstance(default, list | tuple) else \
            str(default)
        return f"{text} (default: {shown.replace('%', '%%')})"


def parser(prog: str | None, description: str, examples: Sequence[str]
           ) -> argparse.ArgumentParser:
    """A command's parser: a one-line ``description`` (what the command does, a full
    sentence) and its ``examples`` under the options."""
    head = "example:" if len(examples) == 1 else "examples:"
    return argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=HelpFormatter,
        epilog=head + "\n" + "\n".join(f"  {e}" for e in examples))


#: Most points a grid spec may ask for on one axis (a typo such as 2e9 would otherwise
#: allocate gigabytes before the sweep's own checks run).
MAX_GRID_POINTS = 1_000_000


def number(text: str) -> float:
    """A finite real number, ``ArgumentTypeError`` otherwise."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    return value


def assignment(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` with a numeric value, e.g. ``u0=1.15``."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), number(value)


def grid(text: str) -> np.ndarray:
    """A 1-d grid: ``geom:START:STOP:N``, ``lin:START:STOP:N`` or ``a,b,c``."""
    kind, _, rest = text.partition(":")
    if kind in ("geom", "lin"):
        parts = rest.split(":")
        if len(parts) != 3:
            raise argparse.ArgumentTypeError(
                f"expected {kind}:START:STOP:N, got {text!r}")
        start, stop = number(parts[0]), number(parts[1])
        try:
            n = int(parts[2])
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"N must be a whole number in {text!r}, got {parts[2]!r}") from None
        if not 1 <= n <= MAX_GRID_POINTS:
            raise argparse.ArgumentTypeError(
                f"N must be in [1, {MAX_GRID_POINTS}] in {text!r}, got {n}")
        if kind == "geom":
            if start <= 0 or stop <= 0:
                raise argparse.ArgumentTypeError(
                    f"a geometric grid needs START, STOP > 0, got {text!r}")
            return np.geomspace(start, stop, n)
        return np.linspace(start, stop, n)
    try:
        values = [number(v) for v in text.split(",") if v.strip()]
    except argparse.ArgumentTypeError as e:
        raise argparse.ArgumentTypeError(
            f"expected geom:START:STOP:N, lin:START:STOP:N or a comma-separated list, "
            f"got {text!r} ({e})") from None
    if not values:
        raise argparse.ArgumentTypeError(f"empty grid: {text!r}")
    return np.array(values)


def add_plant_arguments(p: argparse.ArgumentParser, cases: bool) -> None:
    """``--law``, ``--set`` (and ``--case`` for time histories): which plant to run."""
    src = p.add_mutually_exclusive_group()
    src.add_argument("--law", choices=sorted(FRICTION_LAWS),
                     help="friction law, with the paper's other parameters (default: coulomb)")
    if cases:
        src.add_argument("--case", choices=list(PAPER_CASES),
                         help="one of the paper's time-history cases (Figs. 4-7)")
    p.add_argument("--set", dest="sets", type=assignment, action="append", default=[],
                   metavar="NAME=VALUE",
                   help="set a parameter (lam, eta, nu, u0, V, xfk, xfs, b1, b3, u1, u2); "
                        "repeatable")


def plant(args: argparse.Namespace) -> OscillatorParams:
    """The plant ``--law``/``--case`` and ``--set`` describe (``ValueError``/``TypeError``
    from ``OscillatorParams``, naming the field, for a bad value)."""
    base = dict(PAPER_CASES[args.case]) if getattr(args, "case", None) else {}
    law = args.law or "coulomb"  # (the paper's cases are all Coulomb)
    return OscillatorParams.preset(law, **{**base, **dict(args.sets)})


def out_dir(text: str) -> Path:
    """An output folder: an existing file there, or a file where one of the folders above
    it should be (``--out report.txt/run``), is refused up front, before a run whose
    results could not be written."""
    path = Path(text)
    try:
        if path.exists() and not path.is_dir():
            raise argparse.ArgumentTypeError(f"{text!r} is a file, not a folder")
        for parent in path.absolute().parents:
            if parent.exists():
                if not parent.is_dir():
                    raise argparse.ArgumentTypeError(
                        f"{text!r} cannot be made: {str(parent)!r} is a file, not a folder")
                break
    except OSError as e:  # (a name too long, a loop of symlinks)
        raise argparse.ArgumentTypeError(f"{text!r} cannot be a folder: {e.strerror}") from None
    return path


def positive_int(text: str) -> int:
    """A count of at least 1 (workers, say): 0 or a negative count is refused up front
    instead of meaning "none" or hanging."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return n


def unique_axes(pairs: Sequence[tuple[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """``(name, grid)`` pairs (repeated ``--axis`` options) as a dict; ``ValueError``
    naming a parameter given twice, which a dict would otherwise keep once, silently."""
    out: dict[str, np.ndarray] = {}
    for name, values in pairs:
        if name in out:
            raise ValueError(f"--axis: parameter {name!r} is given twice")
        out[name] = values
    return out
