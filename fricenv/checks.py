"""Argument checks shared by the public entry points: a wrong type gets a ``TypeError`` and
a bad value a ``ValueError``, each naming the argument and what was passed, instead of a
failure deep inside numpy, numba or ``range``."""

from __future__ import annotations

import math
import numbers
import operator
import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

#: Largest float64 magnitude: a real number beyond it (a huge int or Fraction) cannot be
#: converted, and ``float`` would raise an ``OverflowError`` naming nothing.
FLOAT_MAX = sys.float_info.max


def _int_head(n: int) -> tuple[str, int]:
    """A huge int as ``1.23456e+400`` and its number of digits, without converting all of it
    to a string."""
    m = abs(n)
    digits = int(m.bit_length() * math.log10(2)) + 1
    if 10 ** (digits - 1) > m:  # the estimate may be one too large
        digits -= 1
    head = str(m // 10 ** (digits - 6))
    return f"{'-' if n < 0 else ''}{head[0]}.{head[1:]}e+{digits - 1}", digits


def short_repr(value: Any, limit: int = 80) -> str:
    """``repr(value)`` for an error message, abbreviated when long: a huge int as its leading
    digits and its length (``repr`` of an int beyond 4300 digits even raises)."""
    if is_int(value) and abs(int(value)).bit_length() > 200:
        text, digits = _int_head(int(value))
        return f"{text} (an int of {digits} digits)"
    if isinstance(value, numbers.Rational) and not isinstance(value, numbers.Integral):
        parts = [f"~{_int_head(int(k))[0]}" if abs(int(k)).bit_length() > 200 else repr(int(k))
                 for k in (value.numerator, value.denominator)]
        return f"{type(value).__name__}({parts[0]}, {parts[1]})"
    try:
        r = repr(value)
    except ValueError:  # e.g. an int subclass beyond the str conversion limit
        return f"<{type(value).__name__} too long to print>"
    return r if len(r) <= limit else f"{r[:limit - 20]}...{r[-15:]}"


def got(value: Any) -> str:
    """The end of an error message: what was passed, and its type."""
    return f"got {short_repr(value)} ({type(value).__name__})"


def is_int(value: Any) -> TypeGuard[int | np.integer]:
    """An integer (numpy's included; bools are not, floats are not even when whole)."""
    return isinstance(value, (numbers.Integral, np.integer)) and not isinstance(
        value, (bool, np.bool_)
    )


def check_int(name: str, value: Any, minimum: int | None = None,
              maximum: int | None = None) -> int:
    """``value`` as an int: ``TypeError`` unless an integer (a float would be truncated),
    ``ValueError`` if below ``minimum`` or above ``maximum``."""
    if not is_int(value):
        raise TypeError(f"{name} must be an integer, {got(value)}")
    n = operator.index(value)
    if minimum is not None and n < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {short_repr(value)}")
    if maximum is not None and n > maximum:
        raise ValueError(f"{name} must be an integer <= {maximum}, got {short_repr(value)}")
    return n


def is_real(value: Any) -> bool:
    """A real number, as the plant parameters take them (bools are not)."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def check_real(name: str, value: Any, limit: float = FLOAT_MAX) -> float:
    """``value`` as a float; ``TypeError`` naming ``name`` unless it is a real number,
    ``ValueError`` naming it for one beyond float64 (a huge int or Fraction), whose
    conversion would raise a bare ``OverflowError``. ``limit``: the bound the message cites."""
    if not is_real(value):
        raise TypeError(f"{name} must be a real number, {got(value)}")
    try:
        return float(value)
    except OverflowError:
        bound = f"+-{limit:g}" + (" (float64)" if limit == FLOAT_MAX else "")
        raise ValueError(f"{name} must lie within {bound}, got {short_repr(value)}") from None


def check_finite_real(name: str, value: Any, limit: float = FLOAT_MAX) -> float:
    """``value`` as a finite float: ``TypeError`` naming ``name`` unless it is a real number
    (:func:`check_real`), ``ValueError`` if it is NaN or infinite."""
    x = check_real(name, value, limit)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {short_repr(value)}")
    return x


def check_bounded_real(name: str, value: Any, limit: float) -> float:
    """``value`` as a finite float of magnitude at most ``limit`` (:func:`check_finite_real`,
    then ``ValueError`` naming ``name`` beyond the limit)."""
    x = check_finite_real(name, value, limit)
    if abs(x) > limit:
        raise ValueError(f"{name} must lie within +-{limit:g} (the model is dimensionless, "
                         f"its quantities O(1)), got {short_repr(value)}")
    return x


def check_rtol(value: Any) -> float:
    """A relative tolerance as a float: ``TypeError`` unless a real number, ``ValueError``
    unless in (0, 1) (at 1 or more the steps would track nothing)."""
    x = check_finite_real("rtol", value)
    if not 0.0 < x < 1.0:
        raise ValueError(f"rtol must lie in (0, 1), got {short_repr(value)}")
    return x


def check_bool(name: str, value: Any) -> bool:
    """``value`` as a bool; ``TypeError`` naming ``name`` unless it is one (numpy's included:
    a truthy string such as ``'no'`` or a number would otherwise pass as True)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool (True or False), {got(value)}")
    return bool(value)


def real_array(value: Any, what: str) -> np.ndarray:
    """``value`` as a float64 array: ``TypeError`` unless it is made of real numbers (None,
    strings, dicts, complex or bools would otherwise become NaN, a parsed float or a numba
    typing error; Fractions convert), ``ValueError`` for ragged nesting or a number beyond
    float64 (a huge int, which would raise a bare ``OverflowError``). ``what`` opens the
    message ("u0 must be ...")."""
    a = None
    if value is not None and not isinstance(value, (str, bytes)):
        try:
            a = np.asarray(value)
        except ValueError as exc:  # ragged nesting: numbers, but no array shape
            raise ValueError(f"{what}, got {short_repr(value)}") from exc
        except TypeError:  # e.g. a failing __array__
            a = None
        if a is not None and a.dtype.kind == "O":
            if not all(is_real(v) for v in a.flat):
                a = None
            else:
                for v in a.flat:  # (only object arrays can hold numbers beyond float64)
                    try:
                        float(v)
                    except OverflowError:
                        raise ValueError(f"{what}, each within +-{FLOAT_MAX:g} (float64), "
                                         f"got {short_repr(v)}") from None
                a = a.astype(np.float64)
    if a is None or a.dtype.kind not in "iuf":  # (bools are flags, not amounts)
        raise TypeError(f"{what}, {got(value)}")
    return a.astype(np.float64)


def items_of(value: Any) -> list | None:
    """The items of a list-like ``value`` (not a string or a mapping), else None."""
    if isinstance(value, Iterable) and not isinstance(value, (str, bytes, Mapping)):
        try:
            return list(value)
        except TypeError:  # e.g. a 0-d array
            return None
    return None


def real_tuple(name: str, value: Any, n: int, what: str) -> tuple[float, ...]:
    """``value`` as ``n`` floats; ``TypeError`` unless it is a sequence of real numbers,
    ``ValueError`` unless it holds ``n`` of them (``what``: the message's description)."""
    items = items_of(value)
    if items is None:
        raise TypeError(f"{name} must be {what}, {got(value)}")
    if len(items) != n:
        raise ValueError(f"{name} must be {what}, got {len(items)} values: {short_repr(value)}")
    return tuple(check_real(f"{name}[{i}]", v) for i, v in enumerate(items))


def check_dict(name: str, value: Any, what: str = "a dict") -> None:
    """``TypeError`` naming ``name`` unless ``value`` is a mapping or None."""
    if value is not None and not isinstance(value, Mapping):
        raise TypeError(f"{name} must be {what} or None, {got(value)}")


def check_path(name: str, value: Any, what: str = "") -> Path:
    """``value`` as a Path: ``TypeError`` naming ``name`` unless a str or an ``os.PathLike``
    of str (an int would be a file descriptor to ``open``, bytes a second spelling);
    ``what`` ("folder", "file name") ends the type's description in the message."""
    if isinstance(value, os.PathLike):
        fs = os.fspath(value)
        if isinstance(fs, str):
            return Path(fs)
    elif isinstance(value, str):
        return Path(value)
    kind = f"os.PathLike {what}" if what else "os.PathLike"
    raise TypeError(f"{name} must be a str or {kind}, {got(value)}")


def check_output_dir(name: str, path: Any) -> Path:
    """``path`` as a folder a run may create or write into: ``ValueError`` naming ``name``
    if it, or the nearest of its parents that exists, is not a folder. Checked before the
    work, so a long run cannot end in ``FileExistsError`` with its results unsaved."""
    p = Path(path)
    for q in (p, *p.parents):
        if q.exists():
            if not q.is_dir():
                raise ValueError(f"{name} {str(path)!r}: {str(q)!r} exists and is not a folder")
            break
    return p


def check_output_file(name: str, path: Any) -> Path:
    """``path`` as a file a run may (over)write: ``ValueError`` naming ``name`` if it is a
    folder or its folder cannot be made (see :func:`check_output_dir`)."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{name} {str(path)!r} is a folder, not a file")
    check_output_dir(name, p.parent)
    return p
