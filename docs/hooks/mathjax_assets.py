"""MkDocs hook: serve MathJax from the site itself, so equations render without a network.

The pages write equations in TeX, which ``pymdownx.arithmatex`` (generic mode) wraps in
``<span class="arithmatex">`` and ``<div class="arithmatex">``; MathJax 3 typesets them in
the browser (configured by ``javascripts/mathjax-config.js``). MathJax's files come from
the Python package django-static-mathjax, a dependency of the ``docs`` extra that holds
MathJax's browser build and needs nothing of Django. This hook adds the files the pages
use to the site under ``javascripts/mathjax/``, as if they were in the docs folder: the
combined TeX-to-CommonHTML script, its web fonts, the TeX extensions MathJax loads on
demand, its menu and its accessibility parts.
"""

from __future__ import annotations

import importlib.metadata
import posixpath
from pathlib import Path
from typing import Any

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

DISTRIBUTION = "django-static-mathjax"
PACKAGE_DIR = "mathjax/static/mathjax/es5"  # MathJax's es5 folder inside the distribution
SITE_DIR = "javascripts/mathjax"
# what the pages load, relative to the es5 folder: the script itself and what it fetches
# from its own folder (fonts for CommonHTML output, \require'd or autoloaded TeX packages,
# the context menu's parts and the speech rules its accessibility options load)
ASSETS = (
    "tex-chtml.js",
    "output/chtml/fonts/woff-v2/*.woff",
    "input/tex/extensions/*.js",
    "ui/*.js",
    "a11y/*.js",
    "sre/mathmaps/base.json",
    "sre/mathmaps/en.json",
)


def mathjax_folder() -> Path:
    """MathJax's es5 folder as installed; ``PluginError`` saying what to install if absent."""
    try:
        dist = importlib.metadata.distribution(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError as e:
        raise PluginError(f"the docs serve MathJax from the package {DISTRIBUTION}, which is "
                          "not installed: pip install -e '.[docs]'") from e
    folder = Path(str(dist.locate_file(PACKAGE_DIR)))
    if not (folder / ASSETS[0]).is_file():
        raise PluginError(f"{DISTRIBUTION} {dist.version} has no {PACKAGE_DIR}/{ASSETS[0]} "
                          f"(looked in {folder})")
    return folder


def on_files(files: Files, config: MkDocsConfig, **kwargs: Any) -> Files:
    """Add MathJax's files to the site under ``javascripts/mathjax/``."""
    folder = mathjax_folder()
    for pattern in ASSETS:
        matches = sorted(p for p in folder.glob(pattern) if p.is_file())
        if not matches:
            raise PluginError(f"{DISTRIBUTION}: nothing matches {pattern} in {folder}")
        for path in matches:
            uri = posixpath.join(SITE_DIR, path.relative_to(folder).as_posix())
            files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files
