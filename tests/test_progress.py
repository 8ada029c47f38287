"""fricenv.progress: bars whose rate and remaining time leave out compile time."""

from __future__ import annotations

import io

from fricenv import _compile_listener, progress


def test_the_rate_leaves_out_the_seconds_spent_compiling(monkeypatch):
    """A first chunk that took 30 s, of which 29.9 s compiling, counts as 0.1 s: the rate
    and the remaining time are those of the running kernels."""
    clock = {"now": 1000.0, "compiled": 5.0}
    monkeypatch.setattr(_compile_listener, "compile_seconds", lambda: clock["compiled"])
    bar = progress.tqdm(total=1280, file=io.StringIO(), mininterval=0, smoothing=0.1)
    monkeypatch.setattr(bar, "_time", lambda: clock["now"])
    bar.start_t = bar.last_print_t = clock["now"]
    clock["now"] += 30.0
    clock["compiled"] += 29.9
    bar.update(64)
    rate = bar.format_dict["rate"]
    assert abs(rate - 640.0) < 1e-6, rate  # 64 cells in 0.1 s
    assert bar.format_dict["elapsed"] < 0.2
    clock["now"] += 0.1
    bar.update(64)
    assert abs(bar.format_dict["rate"] - 640.0) < 1e-6
    bar.close()


def test_a_disabled_bar_counts_nothing(monkeypatch):
    monkeypatch.setattr(_compile_listener, "compile_seconds", lambda: 3.0)
    with progress.tqdm(total=3, disable=True) as bar:
        bar.update(1)
        assert bar.n == 0  # (tqdm's own: a disabled bar does not count)
