"""The Python examples of README.md and of every page under docs/ run, so they cannot rot.

For each page, the ```python fenced blocks run in order in one namespace, in a temporary
working directory (files they write land there) with ``MPLBACKEND=Agg``. Conventions:

- a block whose previous non-blank line is ``<!-- skip: REASON -->`` is not run (kept for
  commands that need minutes or a trained run folder); a mark without a reason fails;
- a block that starts a Dask ``LocalCluster`` keeps its work under ``if __name__ ==
  "__main__":`` (spawned workers import the script again), so in the page's namespace it
  only defines; it is also run as a script in a subprocess, its ``n = ...`` line (the grid
  size) set to 2;
- a ```text block that directly follows a ```python block (only blank lines between) is
  that block's expected standard output, compared line by line (trailing spaces ignored).

Shell examples go in ```bash blocks, which are never run. A second test checks that every
relative link in README.md points to a file of the repository (and, for a link into a
Markdown page with ``#anchor``, to one of its headings), since GitHub shows README.md
outside the docs site, where ``mkdocs build --strict`` checks the pages' own links.
"""

from __future__ import annotations

import contextlib
import difflib
import io
import os
import re
import subprocess
import sys
import unicodedata
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])
SKIP_MARK = re.compile(r"^<!-- skip(?::\s*(?P<reason>.*?))?\s*-->$")
_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^`\s]*)")


@dataclass
class Block:
    lang: str
    line: int  # 1-based line of the first code line
    code: str
    skip: bool
    expected: str | None = None  # the following ```text block, for a python block
    skip_reason: str = ""  # what the skip mark says


def fenced_blocks(text: str, name: str) -> list[Block]:
    """Every fenced block of a Markdown page in order; ``ValueError`` for an unclosed one."""
    lines = text.splitlines()
    blocks: list[Block] = []
    after_block = False  # only blank lines since the last closing fence
    prev = ""  # previous non-blank line outside blocks
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            if lines[i].strip():
                prev, after_block = lines[i].strip(), False
            i += 1
            continue
        indent, fence, lang = len(m["indent"]), m["fence"], m["info"].lower()
        close = re.compile(rf"^[ \t]*{re.escape(fence[0])}{{{len(fence)},}}[ \t]*$")
        start = i + 1
        j = start
        while j < len(lines) and not close.match(lines[j]):
            j += 1
        if j == len(lines):
            raise ValueError(f"{name}:{i + 1}: fenced block is never closed")
        code = "\n".join(line[indent:] if not line[:indent].strip() else line
                         for line in lines[start:j])  # the fence's indent removed
        mark = SKIP_MARK.match(prev)
        block = Block(lang, start + 1, code + "\n", mark is not None,
                      skip_reason=(mark["reason"] or "") if mark else "")
        if (lang == "text" and after_block and blocks and blocks[-1].lang == "python"
                and blocks[-1].expected is None):
            blocks[-1].expected = block.code
        blocks.append(block)
        prev, after_block = "", True
        i = j + 1
    return blocks


def _rel(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def _normalised(text: str) -> list[str]:
    lines = [line.rstrip() for line in text.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    return lines


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_page_examples_run(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = [b for b in fenced_blocks(page.read_text(encoding="utf-8"), _rel(page))
              if b.lang == "python" and not b.skip]
    if not blocks:
        return  # the page parsed (every fence closed) and has nothing to run
    monkeypatch.setenv("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    try:
        for block in blocks:
            # blank lines in front, so a traceback names the page's own line numbers
            code = compile("\n" * (block.line - 1) + block.code, _rel(page), "exec")
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                exec(code, namespace)
            if block.expected is not None:
                got, want = _normalised(out.getvalue()), _normalised(block.expected)
                if got != want:
                    diff = "\n".join(difflib.unified_diff(want, got, "documented", "printed",
                                                          lineterm=""))
                    pytest.fail(f"{_rel(page)}:{block.line}: the block prints something "
                                f"else than the page shows:\n{diff}")
    finally:
        plt.close("all")
        for value in namespace.values():  # environments the examples left open
            close = getattr(value, "close", None)
            if callable(close) and type(value).__module__.startswith(("fricenv", "gymnasium",
                                                                     "stable_baselines3")):
                with contextlib.suppress(Exception):
                    close()


def _slug(heading: str) -> str:
    """The anchor MkDocs gives a Markdown heading (Python-Markdown's ``toc.slugify``;
    GitHub's is the same for headings of plain words)."""
    text = unicodedata.normalize("NFKD", re.sub(r"[`*]", "", heading))
    text = re.sub(r"[^\w\s-]", "", text.encode("ascii", "ignore").decode()).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def _anchors(page: Path) -> set[str]:
    text = page.read_text(encoding="utf-8")
    outside = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)  # no headings in code
    return {_slug(m[1]) for m in re.finditer(r"^#{1,6}[ \t]+(.+?)[ \t#]*$", outside, re.M)}


_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_REF = re.compile(r"^\s*\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+\"[^\"]*\")?\s*$", re.M)


def test_readme_links_point_to_files() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)  # links in code are not links
    targets = [m[1] for m in _LINK.finditer(text)] + [m[1] for m in _REF.finditer(text)]
    assert targets, "README.md has no links"
    broken = []
    for target in targets:
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
            continue  # a URL (https:, mailto:) or an anchor of the README itself
        path, _, anchor = target.partition("#")
        file = (ROOT / path).resolve()
        if not file.exists() or ROOT not in file.parents:
            broken.append(f"{target}: no such file in the repository")
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
            broken.append(f"{target}: {path} has no heading with anchor #{anchor}")
    assert not broken, "broken links in README.md:\n" + "\n".join(broken)


#: A repository file named in inline code (`tests/test_x.py`); names with a placeholder in
#: capitals (`scripts/bench_NAME.py`) and environment ids (`fricenv/StickSlip-v0`) are not
#: files.
_FILE_NAMED = re.compile(r"`((?:tests|scripts|fricenv|agents|docs|\.ci)/[\w./-]+\.[a-z]+)`")


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_files_named_in_pages_exist(page: Path) -> None:
    """A file the text names for the reader to open (a test, a script, a module) exists:
    renaming or folding one leaves no page pointing at nothing."""
    names = {m[1] for m in _FILE_NAMED.finditer(page.read_text(encoding="utf-8"))}
    missing = sorted(n for n in names
                     if not re.search(r"[A-Z]{3,}", n) and not (ROOT / n).exists())
    assert not missing, f"{_rel(page)} names files the repository does not have: {missing}"


@pytest.mark.parametrize("page", PAGES, ids=_rel)
def test_skipped_blocks_say_why(page: Path) -> None:
    unexplained = [b.line for b in fenced_blocks(page.read_text(encoding="utf-8"), _rel(page))
                   if b.skip and not b.skip_reason]
    assert not unexplained, (f"{_rel(page)}: blocks at lines {unexplained} are skipped "
                             "without a reason (<!-- skip: why -->)")


def cluster_blocks() -> list[tuple[Path, Block]]:
    """The Python blocks of the pages that start a Dask cluster."""
    return [(page, b) for page in PAGES
            for b in fenced_blocks(page.read_text(encoding="utf-8"), _rel(page))
            if b.lang == "python" and "LocalCluster(" in b.code]


def test_the_cluster_snippets_are_found_and_guarded() -> None:
    found = cluster_blocks()
    assert found, "no docs snippet starts a LocalCluster"
    for page, block in found:
        assert 'if __name__ == "__main__":' in block.code, f"{_rel(page)}:{block.line}"
        assert re.search(r"^n = \d+", block.code, re.M), f"{_rel(page)}:{block.line}"
        assert not block.skip, f"{_rel(page)}:{block.line}"


@pytest.mark.parametrize(("page", "block"), cluster_blocks(),
                         ids=lambda x: _rel(x) if isinstance(x, Path) else str(x.line))
def test_cluster_snippets_run_as_scripts(page: Path, block: Block, tmp_path: Path) -> None:
    """Pasted into a file and run with ``python``, on a 2 x 2 grid: the workers spawn,
    import the script again and do not rerun it."""
    script = tmp_path / "snippet.py"
    script.write_text(re.sub(r"^n = \d+", "n = 2", block.code, count=1, flags=re.M))
    env = {**os.environ, "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    res = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, f"{_rel(page)}:{block.line}\n{res.stderr[-3000:]}"
    assert "Traceback" not in res.stderr, res.stderr[-3000:]


def test_block_parser() -> None:
    page = "\n".join([
        "text", "```python", "print(1)", "```", "", "```text", "1", "```",
        "<!-- skip: slow -->", "```python", "raise SystemExit", "```",
        "- item", "  ```bash", "  echo hi", "  ```",
    ])
    blocks = fenced_blocks(page, "t.md")
    assert [(b.lang, b.skip, b.line) for b in blocks] == [
        ("python", False, 3), ("text", False, 7), ("python", True, 11), ("bash", False, 15)]
    assert blocks[0].expected == "1\n" and blocks[0].code == "print(1)\n"
    assert blocks[2].skip_reason == "slow"
    assert fenced_blocks("<!-- skip -->\n```python\n1\n```\n", "t.md")[0].skip
    assert blocks[3].code == "echo hi\n"
    with pytest.raises(ValueError, match="never closed"):
        fenced_blocks("```python\nprint(1)\n", "t.md")


def test_one_documented_command_writes_into_docs_results() -> None:
    """The shipped results are regenerated on purpose only: of all the shell commands the
    pages show, those that name ``docs/results`` are the commands that regenerate the
    published pages: the control benchmark, the MPC's per-scene search, the comparisons
    with the tuned MPC (of the benchmark's PPO and of PPO on short episodes), the noise
    report and the identification benchmark."""
    hits = [(_rel(page), line.strip()) for page in PAGES
            for b in fenced_blocks(page.read_text(encoding="utf-8"), _rel(page))
            if b.lang in ("bash", "sh", "shell", "console")
            for line in b.code.splitlines() if "docs/results" in line]
    assert hits == [("docs/control.md",
                     "python -m fricenv_agents.benchmark --out docs/results --jobs 2"),
                    ("docs/control.md", "python -m fricenv_agents.mpc_tuning --out docs/results"),
                    ("docs/control.md", "python -m fricenv_agents.mpc_compare --out docs/results"),
                    ("docs/control.md", "python -m fricenv_agents.mpc_gap --out docs/results"),
                    ("docs/control.md", "python -m fricenv_agents.noise_report --out docs/results"
                     "   # from the benchmark's CSV, seconds"),
                    ("docs/results/identification.md",
                     "python scripts/identification_benchmark.py --out docs/results")]
