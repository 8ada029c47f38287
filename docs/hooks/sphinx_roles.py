"""MkDocs hook: show the docstrings' Sphinx roles as plain code.

The package's docstrings read well in ``help()`` and in editors, and they name other
objects the Sphinx way (``:func:`run_stats```). mkdocstrings renders them as Markdown, where
such a role would print literally as ``:func:`` followed by a code span; this hook keeps
the code span and drops the role (and the ``~`` that shortens a dotted name), after the
page's HTML is made.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(
    r":(?:py:)?(?:func|class|mod|meth|attr|data|obj|exc|const):<code>~?([^<]*)</code>")


def on_page_content(html: str, **kwargs: Any) -> str:
    """Replace ``:role:<code>name</code>`` with ``<code>name</code>`` in a page's HTML."""
    return _ROLE.sub(r"<code>\1</code>", html)
