"""MkDocs hook: keep identifiers in one piece.

mkdocs-material lets inline code break anywhere when its line is full, so a narrow table
column cuts an env id such as ``fricenv/StickSlip-v0`` mid-word. This hook gives inline code
without spaces (a name, an id, a path: an identifier) the class ``identifier``, which
``stylesheets/extra.css`` keeps on one line on screens wide enough for it. Code with
spaces still breaks, at its spaces only: each of its words goes in a ``<span
class="identifier">`` (a browser would otherwise break ``--quick`` after its first hyphen).
"""

from __future__ import annotations

import re
from typing import Any

# <code> with no attributes and no markup inside: inline code (highlighted blocks carry
# <span>s, and a block's text ends with a newline)
_IDENTIFIER = re.compile(r"<code>([^<\s]+)</code>")
# inline code with spaces and no markup inside, and the words in it
_PHRASE = re.compile(r"<code>([^<\n]*[ \t][^<\n]*)</code>")
_WORD = re.compile(r"[^\s]+")


def _words_kept_whole(match: re.Match[str]) -> str:
    words = _WORD.sub(lambda w: f'<span class="identifier">{w.group(0)}</span>', match.group(1))
    return f"<code>{words}</code>"


def on_page_content(html: str, **kwargs: Any) -> str:
    """Add ``class="identifier"`` to every inline ``<code>`` whose text has no whitespace,
    and to each word of those that have some."""
    html = _IDENTIFIER.sub(r'<code class="identifier">\1</code>', html)
    return _PHRASE.sub(_words_kept_whole, html)
