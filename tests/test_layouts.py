"""Every index layout is declared once, and no two of its slots overlap."""

from __future__ import annotations

import pytest

from fricenv.core import workspace
from fricenv.envs import kernels, scenes, tables
from fricenv.slots import Layout

LAYOUTS = [workspace.WORKSPACE, workspace.TONE_KEYS, *tables.LAYOUTS]


@pytest.mark.parametrize("layout", LAYOUTS, ids=lambda lay: lay.name)
def test_slots_tile_the_array_without_overlap(layout: Layout) -> None:
    covered = [0] * layout.size
    for name, offset, size in layout.slots:
        for k in range(offset, offset + size):
            covered[k] += 1
        assert size >= 1, name
    assert covered == [1] * layout.size  # each entry in exactly one slot: no overlap, no gap


def _named_constants(module, layout: Layout) -> dict[str, int]:
    return {name: getattr(module, name) for name, _, _ in layout.slots if hasattr(module, name)}


@pytest.mark.parametrize("module, layout", [(workspace, workspace.WORKSPACE),
                                            (workspace, workspace.TONE_KEYS),
                                            (tables, tables.CONFIG), (tables, tables.TABLE)])
def test_every_slot_is_bound_to_its_offset(module, layout: Layout) -> None:
    named = _named_constants(module, layout)
    assert set(named) == {name for name, _, _ in layout.slots}
    assert named == layout.offsets()


def test_the_draws_follow_the_scenes_order() -> None:
    names = [name for name, _, _ in tables.DRAWS.slots]
    assert names == [*scenes.RANDOMIZABLE, *scenes.INITIAL]
    for name, offset, _ in tables.DRAWS.slots:
        assert getattr(kernels, "D_" + name.upper()) == offset


def test_the_environments_share_one_declaration() -> None:
    for name in ("I_X0", "I_NU", "N_INIT", "N_DRAWS"):
        assert getattr(scenes, name) == getattr(tables, name)
    for name in ("C_DT", "C_NU_START", "N_CFG", "T_WORK", "N_TABLE", "O_NU", "N_OBS"):
        assert getattr(kernels, name) == getattr(tables, name)


def test_a_layout_refuses_a_name_twice_or_an_empty_slot() -> None:
    lay = Layout("test")
    assert lay.take("a", 3) == 0 and lay.take("b") == 3 and lay.size == 4
    with pytest.raises(ValueError, match="twice"):
        lay.take("a")
    with pytest.raises(ValueError, match="size"):
        lay.take("c", 0)
