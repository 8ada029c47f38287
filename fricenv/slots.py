"""Index layouts of small float64 arrays, declared once as an ordered list of slots.

A layout is built by taking slots in order: each ``take`` returns the next free offset, so
offsets are computed, never written by hand, and adding a slot renumbers everything after it
without a search for literal numbers. ``slots`` keeps the declaration (name, offset, size),
which the tests check for overlaps and gaps.
"""

from __future__ import annotations


class Layout:
    """An ordered list of named slots of an array; ``size`` is the array's length."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.slots: list[tuple[str, int, int]] = []
        self.size = 0

    def take(self, name: str, size: int = 1) -> int:
        """Declare the next slot (``size`` entries) and return its offset."""
        if size < 1:
            raise ValueError(f"{self.name}: slot {name!r} needs a size >= 1, got {size}")
        if any(name == n for n, _, _ in self.slots):
            raise ValueError(f"{self.name}: slot {name!r} declared twice")
        offset = self.size
        self.slots.append((name, offset, size))
        self.size += size
        return offset

    def group(self, *names: str) -> tuple[int, ...]:
        """Declare one-entry slots ``names`` in order; their offsets."""
        return tuple(self.take(n) for n in names)

    def offsets(self) -> dict[str, int]:
        return {n: o for n, o, _ in self.slots}
