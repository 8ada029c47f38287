"""The vector environment's random streams: a generator per plant, and its next draws.

Plant ``i`` of ``StickSlipVectorEnv`` (``fricenv.envs.vector``) owns its own random
generator, seeded ``seed + i`` as ``SyncVectorEnv`` seeds its sub-environments, and
``PlantDraws`` keeps the uniforms of its next ``DRAW_ROWS`` episodes in a buffer: one
``rng.random`` call yields the same numbers as that many calls of one episode's size, so
the step kernel autoresets a plant in place with exactly the numbers a single environment
would draw at its next ``reset()``, and Python refills a plant's buffer only every
``DRAW_ROWS`` episodes. The buffers' read positions (``cursor``) live in the kernel's
counters; the methods are handed them. ``plant_options`` splits reset options given as
arrays of one value per plant into each plant's own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np
from gymnasium.utils import seeding

from fricenv.checks import got, is_int, items_of
from fricenv.envs.scenes import N_DRAWS
from fricenv.envs.setup import EnvSetup

#: Episodes' worth of uniforms buffered per plant: one ``rng.random`` call every so many
#: episodes instead of one per episode.
DRAW_ROWS = 16



def plant_seeds(seed: Any, n: int) -> list[int | None]:
    """Per-plant seeds from the forms Gymnasium's vector envs take: None, an int (plant i
    gets ``seed + i``) or a list of ``n`` ints or Nones (``TypeError`` / ``ValueError``
    naming the value otherwise, rather than a failure inside the seeding)."""
    if seed is None:
        return [None] * n
    if is_int(seed):
        return [int(seed) + i for i in range(n)]
    seeds = items_of(seed)
    if seeds is None:
        raise TypeError(
            f"seed must be an int, a list of num_envs={n} ints or Nones, or None, {got(seed)}"
        )
    if len(seeds) != n:
        raise ValueError(
            f"seed list must have length num_envs={n}, got {len(seeds)} seeds: {seed!r}"
        )
    for i, s in enumerate(seeds):
        if s is not None and not is_int(s):
            raise TypeError(f"seed[{i}] must be an int or None, {got(s)}")
    return [None if s is None else int(s) for s in seeds]


@contextmanager
def named_plant(i: int, name: bool = True) -> Iterator[None]:
    """Re-raise a ``TypeError`` or ``ValueError`` with ``options for plant i:`` before its
    message (when ``name``), for errors of options that differ from plant to plant."""
    try:
        yield
    except (TypeError, ValueError) as e:
        if not name:
            raise
        raise type(e)(f"options for plant {i}: {e}") from e


def plant_options(options: Mapping[str, Any], n: int) -> list[dict[str, Any]] | None:
    """Each of ``n`` plants' reset options when some value of ``options`` is a numpy array
    of one value per plant (plant ``i`` gets element ``i``, checked later as a scalar
    option would be); None when every value is one for all plants (a 0-d array is
    one such value, refused by the checks as the single env refuses it). ``ValueError``
    naming the option for an array of another shape."""
    per_plant = [key for key, value in options.items()
                 if isinstance(value, np.ndarray) and value.ndim > 0]
    if not per_plant:
        return None
    for key in per_plant:
        shape = options[key].shape
        if shape != (n,):
            raise ValueError(f"reset option {key!r}: an array holds one value per plant, "
                             f"shape ({n},) for num_envs={n}, got shape {shape}")
    return [{key: _element(value, i) if key in per_plant else value
             for key, value in options.items()} for i in range(n)]


def _element(values: np.ndarray, i: int) -> Any:
    """Element ``i`` of an option's array as a Python scalar (so an error quotes ``1``, not
    ``np.int64(1)``); an object array's element as it is."""
    value = values[i]
    return value.item() if isinstance(value, np.generic) else value


class PlantDraws:
    """The generators, their seeds and the buffered uniforms of ``n`` plants."""

    def __init__(self, n: int):
        self.rngs: list[np.random.Generator | None] = [None] * n
        self.seeds: list[int | None] = [None] * n  # each generator's seed, as reported
        #: each plant's buffered uniforms, DRAW_ROWS episodes ahead (the kernel reads them)
        self.draws = np.zeros((n, DRAW_ROWS, N_DRAWS))

    def refill(self, i: int, cursor: np.ndarray) -> None:
        """Buffer plant ``i``'s next DRAW_ROWS episodes: the numbers as many single-env
        resets would draw, in order, from one call."""
        rng = self.rngs[i]
        assert rng is not None  # (every caller gives the plant a generator first)
        rng.random(out=self.draws[i])
        cursor[i] = 0

    def refill_empty(self, cursor: np.ndarray) -> None:
        """Refill every spent buffer of a plant that has a generator."""
        for i in np.flatnonzero(cursor >= DRAW_ROWS).tolist():
            if self.rngs[i] is not None:
                self.refill(i, cursor)

    def start_episodes(self, idx: np.ndarray, seeds: list[int | None],
                       options: list[dict[str, Any]], cursor: np.ndarray, setup: EnvSetup,
                       P_new: np.ndarray, init: np.ndarray,
                       check: Callable[[list[int]], None],
                       name_plants: bool = False) -> np.ndarray:
        """Write the new episodes of plants ``idx`` (seeded ``seeds``, with reset
        ``options``, each validated against its drawn values) into ``P_new`` and ``init``,
        then ``check`` the plants given options; returns the mask of the plants started.
        If anything is refused, every plant's generator, buffered draws and cursor are put
        back, so a refused reset loses nothing; with ``name_plants`` (options that differ
        from plant to plant) its error names the plant."""
        # all new generators first: a bad seed fails before any plant changes
        fresh = {i: seeding.np_random(s) for i, s in zip(idx.tolist(), seeds, strict=True)
                 if s is not None or self.rngs[i] is None}
        # Spent buffers refilled first (a step that raised may have left some): a plant's
        # next rows are then buffered from its own generator, and all a rejected reset must
        # put back is the generator a new stream replaced and the unread rows it overwrote.
        self.refill_empty(cursor)
        saved = {}  # plant: (generator, cursor, buffered draws), as before
        mask = np.zeros(len(self.rngs), dtype=np.bool_)
        try:
            for i, opt in zip(idx.tolist(), options, strict=True):
                if i in fresh:
                    saved[i] = (self.rngs[i], int(cursor[i]), self.draws[i].copy())
                    self.rngs[i] = fresh[i][0]
                    self.refill(i, cursor)  # a new stream: the old one's rows are dropped
                else:
                    saved[i] = (self.rngs[i], int(cursor[i]), None)
                # the row a single env would draw now
                values = setup.scale(self.draws[i, cursor[i]])
                cursor[i] += 1
                with named_plant(i, name_plants):
                    setup.episode(values, opt or None, P_new[i], init[i])
                mask[i] = True
            check([i for i, o in zip(idx.tolist(), options, strict=True) if o])
        except BaseException:
            for i, (rng, row, draws) in saved.items():
                self.rngs[i] = rng
                if draws is not None:
                    self.draws[i] = draws
                cursor[i] = row
            raise
        for i, (_, used) in fresh.items():
            self.seeds[i] = used
        return mask
