"""The example notebooks in docs/notebooks run from top to bottom without an error.

The docs site shows each notebook with the outputs stored in it (docs/hooks/notebooks.py),
so the stored outputs must be those of a fresh run: the same kinds of output, cell by cell.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).parents[1] / "docs" / "notebooks").glob("*.ipynb"))


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 2


def output_kinds(nb) -> list[list[tuple[str, ...]]]:
    """Per code cell, the kind of each output: a stream's name, or the MIME types shown.

    Consecutive pieces of one stream count once: the kernel splits printed text where it
    happens to flush.
    """
    kinds = []
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        cell_kinds: list[tuple[str, ...]] = []
        for o in cell.get("outputs", []):
            kind = (("stream", o["name"]) if o["output_type"] == "stream"
                    else (o["output_type"], *sorted(o.get("data", {}))))
            if not (kind[0] == "stream" and cell_kinds and cell_kinds[-1] == kind):
                cell_kinds.append(kind)
        kinds.append(cell_kinds)
    return kinds


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    import nbformat
    from nbclient import NotebookClient

    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    # a kernel that compiles prints the compile notice on stderr; the stored outputs, made
    # with the kernels cached, have none, and which run compiles depends on the cache
    monkeypatch.setenv("FRICENV_QUIET", "1")
    nb = nbformat.read(path, as_version=4)
    stored = output_kinds(nb)
    # run where the notebook's files would go, with this checkout's fricenv importable
    # first (fricenv_agents comes from the install, or from the caller's PYTHONPATH)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(path.parents[2]), *filter(None, [os.environ.get("PYTHONPATH")])]))
    NotebookClient(nb, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.output_type == "error"]
    assert not errors
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {})]
    assert images, "the notebook's figures display as images"
    assert output_kinds(nb) == stored, (
        f"{path.name} stores other outputs than a fresh run gives; refresh them with "
        f"FRICENV_QUIET=1 PYTHONPATH=$PWD jupyter execute --inplace "
        f"docs/notebooks/{path.name}")
