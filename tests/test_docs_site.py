"""The built docs site renders its equations and notebooks by itself, with no network.

One strict build of the site (``mkdocs build --strict``, as CI runs it, into a temporary
folder) is checked for what a reader's browser needs: arithmatex's markup around the TeX
of the model, methods and regimes pages, MathJax's files inside the site and referenced
from every page, no script or stylesheet from another host, and the notebooks as pages
with their stored figures. The notebook hook's conversion is also checked on a small
hand-made notebook. How the pages look at 1280 px is checked by
``scripts/docs_screenshots.py``, which needs Chromium.
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[1]
# page -> (inline equations, displayed equations) it has at least
MATH_PAGES = {"index.html": (4, 1), "model/index.html": (40, 6),
              "methods/index.html": (40, 0), "regimes/index.html": (30, 0)}
MATHJAX = "javascripts/mathjax/tex-chtml.js"
NOTEBOOKS = sorted(p.stem for p in (ROOT / "docs" / "notebooks").glob("*.ipynb"))


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built strictly into a temporary folder (about 10 s)."""
    out = tmp_path_factory.mktemp("site")
    # the config path stays relative: docs/mkdocs.yml names its own folder as docs_dir
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet",
           "-f", "docs/mkdocs.yml", "--site-dir", str(out)]
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return out


def load_hook(name: str) -> ModuleType:
    """A module of docs/hooks, imported from its file (the folder is no package)."""
    spec = importlib.util.spec_from_file_location(f"docs_hook_{name}",
                                                  ROOT / "docs" / "hooks" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("page", MATH_PAGES)
def test_pages_carry_tex_in_arithmatex_markup(site, page):
    html = (site / page).read_text(encoding="utf-8")
    inline = re.findall(r'<span class="arithmatex">\\\((.+?)\\\)</span>', html, re.S)
    display = re.findall(r'<div class="arithmatex">\\\[(.+?)\\\]</div>', html, re.S)
    n_inline, n_display = MATH_PAGES[page]
    assert len(inline) >= n_inline, f"{page}: {len(inline)} inline equations"
    assert len(display) >= n_display, f"{page}: {len(display)} displayed equations"
    assert any("\\" in tex for tex in inline), f"{page}: no TeX command"


def test_model_page_states_the_closed_form_in_tex(site):
    html = (site / "model" / "index.html").read_text(encoding="utf-8")
    assert r"e^{-\lambda\tau/2}(c_1 \cos p\tau + c_2 \sin p\tau)" in html
    assert r"\sqrt{(1 - \Omega_i^2)^2 + (\lambda \Omega_i)^2}" in html


def test_mathjax_is_served_from_the_site(site):
    script = site / MATHJAX
    assert script.stat().st_size > 500_000  # the combined TeX-to-CommonHTML build
    fonts = list((site / "javascripts/mathjax/output/chtml/fonts/woff-v2").glob("*.woff"))
    assert len(fonts) > 10
    assert (site / "javascripts/mathjax/input/tex/extensions/boldsymbol.js").is_file()
    assert (site / "javascripts/mathjax-config.js").is_file()
    for page in MATH_PAGES:
        html = (site / page).read_text(encoding="utf-8")
        sources = re.findall(r'<script src="([^"]+)"', html)
        config = [s for s in sources if s.endswith("javascripts/mathjax-config.js")]
        mathjax = [s for s in sources if s.endswith(MATHJAX)]
        assert config and mathjax, f"{page} loads {sources}"
        assert sources.index(config[0]) < sources.index(mathjax[0]), "config before MathJax"


def test_no_page_loads_anything_from_another_host(site):
    remote = re.compile(r'<(?:script|link|img)\b[^>]*\b(?:src|href)="(?:https?:)?//', re.I)
    pages = list(site.rglob("*.html"))
    assert len(pages) > 15
    offenders = [p.relative_to(site).as_posix() for p in pages
                 if remote.search(p.read_text(encoding="utf-8"))]
    assert not offenders


@pytest.mark.parametrize("stem", NOTEBOOKS)
def test_notebooks_are_pages_with_their_outputs(site, stem):
    folder = site / "notebooks" / stem
    html = (folder / "index.html").read_text(encoding="utf-8")
    images = re.findall(r'<img alt="output" src="(cell\d+_\d+\.png)"', html)
    assert images, "the stored figures show"
    assert all((folder / image).is_file() for image in images)
    assert '<span class="kn">import</span>' in html  # highlighted code
    assert 'class="notebook-output highlight"' in html  # outputs set apart
    assert (folder / f"{stem}.ipynb").is_file(), "the notebook is there to download"
    assert 'href="../"' in html  # the note links the page on running the notebooks


def test_links_to_a_notebook_lead_to_its_page(site):
    html = (site / "methods" / "index.html").read_text(encoding="utf-8")
    assert 'href="../notebooks/time_history_and_regime_map/"' in html
    assert not (site / "notebooks" / "time_history_and_regime_map.ipynb").exists()


def test_notebook_markdown_renders_each_kind_of_output():
    hook = load_hook("notebooks")
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_markdown_cell("# Title\n\nText with $x^2$."),
        nbformat.v4.new_code_cell("print('a')\nprint('b')", outputs=[
            nbformat.v4.new_output("stream", name="stdout", text="a\n"),
            nbformat.v4.new_output("stream", name="stdout", text="b ```\n"),
        ]),
        nbformat.v4.new_code_cell("1 / 0", outputs=[
            nbformat.v4.new_output(
                "error", ename="ZeroDivisionError", evalue="division by zero",
                traceback=["\x1b[31mZeroDivisionError\x1b[0m: division by zero"]),
        ]),
        nbformat.v4.new_code_cell("fig", outputs=[
            nbformat.v4.new_output("display_data", data={"image/png": "iVBORw0KGgo=",
                                                         "text/plain": "<Figure>"}),
        ]),
        nbformat.v4.new_raw_cell("left out"),
    ]
    text, images = hook.notebook_markdown(nb, "demo", "INTRO")
    blocks = text.split("\n\n")
    assert blocks[0] == "# Title" and blocks[2] == "INTRO"  # the note follows the title
    out = "{.text .notebook-output}"
    assert f"````{out}\na\nb ```\n````" in text  # one block, a fence longer than ``` inside
    assert f"```{out}\nZeroDivisionError: division by zero\n```" in text  # colours stripped
    assert "![output](demo/cell3_0.png)" in text
    assert images == {"demo/cell3_0.png": b"\x89PNG\r\n\x1a\n"}
    assert "left out" not in text


def test_notebook_markdown_refuses_an_unknown_output():
    hook = load_hook("notebooks")
    nb = nbformat.v4.new_notebook()
    cell = nbformat.v4.new_code_cell("x")
    cell.outputs = [nbformat.from_dict({"output_type": "bogus"})]  # nbformat would refuse it
    nb.cells = [cell]
    with pytest.raises(ValueError, match="unknown notebook output type 'bogus'"):
        hook.notebook_markdown(nb, "demo", "INTRO")
