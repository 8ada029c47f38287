"""MkDocs hook: show the notebooks under ``notebooks/`` as pages, with their stored outputs.

Each ``notebooks/<name>.ipynb`` becomes the page ``notebooks/<name>/``, so that links to the
``.ipynb`` file from other pages lead to the rendered notebook. The notebook is turned into
Markdown before MkDocs renders it, so its text gets the same treatment as every other page
(headings in the table of contents, TeX through arithmatex, highlighted code):

- a Markdown cell is kept as written;
- a code cell becomes a ```` ```python ```` block, followed by its stored outputs: text
  and tracebacks as ```` ```text ```` blocks, PNG and SVG images as files beside the page,
  HTML and Markdown as they are;
- raw cells are left out, as Jupyter's own HTML export leaves them out.

Nothing is executed here: the pages show the outputs stored in the notebooks
(``jupyter execute --inplace`` refreshes them; ``tests/test_notebooks.py`` checks they are
those of a fresh run). The notebook itself is copied beside its page for download.
"""

from __future__ import annotations

import base64
import posixpath
import re
from typing import Any

import nbformat
from mkdocs.config.defaults import MkDocsConfig
from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

NOTEBOOK_DIR = "notebooks/"
# the escape sequences IPython colours tracebacks with; a text block shows them literally
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
_IMAGES = {"image/png": "png", "image/svg+xml": "svg"}


class NotebookPage(File):
    """A notebook's generated Markdown, served as a page at the notebook's own path.

    MkDocs treats only ``.md`` sources as pages; keeping the ``.ipynb`` path lets every
    existing link to the notebook resolve to its page.
    """

    def is_documentation_page(self) -> bool:
        return True


def _fence(text: str, lang: str) -> str:
    """``text`` in a fenced block whose fence is longer than any backtick run inside it.

    Outputs (``lang`` "text") carry the class ``notebook-output``, which
    ``stylesheets/extra.css`` sets apart from the code that printed them.
    """
    longest = max((len(run) for run in re.findall(r"`+", text)), default=0)
    fence = "`" * max(3, longest + 1)
    info = "{.text .notebook-output}" if lang == "text" else lang
    return f"{fence}{info}\n{text.rstrip()}\n{fence}"


def _text(value: str | list[str]) -> str:
    """A notebook field's text, stored either as one string or as a list of lines."""
    return value if isinstance(value, str) else "".join(value)


def _output_markdown(output: Any, image_name: str, images: dict[str, bytes]) -> str:
    """One stored output as Markdown; images go into ``images`` under ``image_name.ext``."""
    kind = output.get("output_type")
    if kind == "stream":
        return _fence(_ANSI.sub("", _text(output["text"])), "text")
    if kind == "error":
        return _fence(_ANSI.sub("", "\n".join(output.get("traceback", []))), "text")
    if kind not in ("execute_result", "display_data"):
        raise ValueError(f"unknown notebook output type {kind!r}")
    data = output.get("data", {})
    for mime, ext in _IMAGES.items():
        if mime in data:
            name = f"{image_name}.{ext}"
            raw = _text(data[mime])
            images[name] = raw.encode() if ext == "svg" else base64.b64decode(raw)
            return f"![output]({name})"
    if "text/html" in data:
        return f'<div class="notebook-output">\n{_text(data["text/html"])}\n</div>'
    if "text/markdown" in data:
        return _text(data["text/markdown"])
    if "text/plain" in data:
        return _fence(_ANSI.sub("", _text(data["text/plain"])), "text")
    return ""  # e.g. a widget's state alone: Jupyter too shows nothing without its kernel


def _merged_streams(outputs: list[Any]) -> list[Any]:
    """``outputs`` with each run of one stream's consecutive pieces joined into one.

    A kernel sends a cell's printed text in pieces as it flushes; Jupyter shows them as one
    block, and so does the page.
    """
    merged: list[Any] = []
    for output in outputs:
        last = merged[-1] if merged else None
        if (last is not None and output.get("output_type") == "stream"
                and last.get("output_type") == "stream" and last.get("name") == output.get("name")):
            merged[-1] = {**last, "text": _text(last["text"]) + _text(output["text"])}
        else:
            merged.append(output)
    return merged


def notebook_markdown(nb: Any, stem: str, intro: str) -> tuple[str, dict[str, bytes]]:
    """The Markdown of notebook ``nb`` and its images, named ``<stem>/cell<i>_<j>.<ext>``.

    ``intro`` goes right after the title cell (a first Markdown cell that opens with a level-1
    heading), else first. Image paths are relative to the notebook's folder, where the
    page's source sits.
    """
    parts: list[str] = []
    images: dict[str, bytes] = {}
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "markdown":
            if cell.get("attachments"):
                raise ValueError(f"cell {i} has attachments, which the docs do not render; "
                                 "save the image as a file and link it")
            parts.append(_text(cell.source))
        elif cell.cell_type == "code":
            parts.append(_fence(_text(cell.source), "python"))
            for j, output in enumerate(_merged_streams(cell.get("outputs", []))):
                block = _output_markdown(output, f"{stem}/cell{i}_{j}", images)
                if block:
                    parts.append(block)
    titled = bool(nb.cells) and nb.cells[0].cell_type == "markdown" and bool(
        re.match(r"#[ \t]", _text(nb.cells[0].source)))
    parts.insert(1 if titled else 0, intro)
    return "\n\n".join(parts) + "\n", images


def _intro(name: str) -> str:
    """The note at the top of a notebook's page: what it shows and how to run it."""
    stem = posixpath.splitext(name)[0]
    return (f'!!! note "A notebook"\n'
            f"    This page shows the notebook [`{name}`]({stem}/{name}) with the outputs "
            f"stored in it. [Notebooks](index.md) says how to run it yourself.")


def on_files(files: Files, config: MkDocsConfig, **kwargs: Any) -> Files:
    """Replace every ``notebooks/*.ipynb`` file by its page, its images and a download copy."""
    for file in list(files):
        uri = file.src_uri
        if not (uri.startswith(NOTEBOOK_DIR) and uri.endswith(".ipynb")):
            continue
        if file.abs_src_path is None:
            raise PluginError(f"{uri}: expected a notebook file on disk")
        name = posixpath.basename(uri)
        stem = posixpath.splitext(name)[0]
        try:
            nb = nbformat.read(file.abs_src_path, as_version=4)
            body, images = notebook_markdown(nb, stem, _intro(name))
        except (OSError, ValueError) as e:  # nbformat's read errors are ValueErrors too
            raise PluginError(f"{uri}: cannot render the notebook: {e}") from e
        files.remove(file)
        files.append(NotebookPage.generated(config, uri, content=body))
        folder = posixpath.join(posixpath.dirname(uri), stem)
        files.append(File.generated(config, posixpath.join(folder, name),
                                    abs_src_path=file.abs_src_path))
        for image, content in images.items():
            files.append(File.generated(
                config, posixpath.join(posixpath.dirname(uri), image), content=content))
    return files
