"""Progress bars whose rate and remaining time leave out numba's compile time.

The first chunk of a regime map, the first batch of an evaluation or the first steps of a
training include compiling their kernels when the cache is cold: 20-50 s against a
fraction of a second once compiled. A plain tqdm bar divides the work done by that time,
and announced 10 minutes left during a 32 s compile of a 40 s job. :class:`tqdm` is
tqdm's bar (``tqdm.auto``: a widget in a notebook) that, on each update, moves its clock
forward past the seconds this process spent compiling since the previous update
(:func:`fricenv._compile_listener.compile_seconds`): its rate, remaining time and elapsed time
count running time only. The compile itself is announced by its own line.
"""

from __future__ import annotations

from typing import Any

from tqdm.auto import tqdm as _tqdm

from . import _compile_listener


class tqdm(_tqdm):  # noqa: N801 (a drop-in for tqdm.auto.tqdm)
    """``tqdm.auto.tqdm`` that leaves compile time out of its rate and remaining time."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._compiled = _compile_listener.compile_seconds()
        super().__init__(*args, **kwargs)

    def update(self, n: float | None = 1) -> bool | None:
        """tqdm's update, after moving the bar's clock past the compile time since the
        previous update (so that the step's rate is its running rate)."""
        spent = _compile_listener.compile_seconds() - self._compiled
        if spent > 0:
            self._compiled += spent
            if not self.disable:
                self.start_t += spent
                self.last_print_t += spent
        return super().update(n)
