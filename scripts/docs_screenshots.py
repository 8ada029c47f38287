#!/usr/bin/env python
"""Screenshots of the docs site in headless Chromium, and a check of its layout.

Builds the site (``mkdocs build --strict``), serves it on 127.0.0.1, and for each page
writes a PNG of a 1280-pixel-wide window and checks, in the page's DOM once MathJax has
typeset it, that

- nothing makes the page scroll sideways (``scrollWidth`` within the window),
- no code block, displayed equation or table scrolls sideways inside the page,
- no inline code without spaces (an identifier, an env id) breaks across lines,
- every equation arithmatex marked was typeset by MathJax, without a TeX error.

Usage: ``python scripts/docs_screenshots.py [--out DIR] [--no-build] [--height PX]
[--pages NAME=PATH ...]``. It needs the ``docs`` extra and Chromium (Debian:
``apt-get install chromium``); the PNGs go to ``out/docs-screenshots/`` and the exit code
is 1 if a check fails. Nothing leaves the machine: the pages load MathJax from the site.
"""

from __future__ import annotations

import argparse
import functools
import html
import http.server
import json
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "out" / "site"  # site_dir of docs/mkdocs.yml
WIDTH = 1280
# name -> (path under the site, window height in pixels: how much of the page the PNG shows)
PAGES = {
    "home": ("", 2400),
    "model": ("model/", 4400),
    "methods": ("methods/", 3000),
    "regimes": ("regimes/", 2400),
    "control": ("control/", 2000),
    "api": ("api/", 2400),
    "notebook": ("notebooks/time_history_and_regime_map/", 3000),
}
CHECK_QUERY = "layout-check"
REPORT_ID = "docs-layout-report"
# Injected into a page served with ?layout-check: once MathJax is done, write the
# problems found as JSON into <pre id="docs-layout-report">, which --dump-dom prints.
CHECK_SCRIPT = """<script>
(function () {
  function label(el) {
    return el.tagName.toLowerCase() + (el.className ? "." + String(el.className).split(" ")[0] : "")
      + ": " + el.textContent.trim().replace(/\\s+/g, " ").slice(0, 70);
  }
  function report() {
    const problems = [];
    const root = document.documentElement;
    if (root.scrollWidth > root.clientWidth) {
      problems.push("the page scrolls sideways: " + root.scrollWidth + " px > "
                    + root.clientWidth);
    }
    const boxes = [".md-content pre > code", ".md-content div.arithmatex",
                   ".md-content .md-typeset__scrollwrap"].join(", ");
    document.querySelectorAll(boxes).forEach(function (el) {
      if (el.scrollWidth > el.clientWidth + 1) {
        problems.push("scrolls sideways by " + (el.scrollWidth - el.clientWidth) + " px: "
                      + label(el));
      }
    });
    document.querySelectorAll(".md-content code").forEach(function (el) {
      const identifier = !/\\s/.test(el.textContent.trim());
      if (!el.closest("pre") && identifier && el.getClientRects().length > 1) {
        problems.push("breaks across lines: " + label(el));
      }
    });
    const marked = document.querySelectorAll(".arithmatex").length;
    const typeset = document.querySelectorAll(".arithmatex mjx-container").length;
    if (typeset < marked) {
      problems.push("MathJax typeset " + typeset + " of " + marked + " equations");
    }
    document.querySelectorAll("mjx-merror").forEach(function (el) {
      problems.push("TeX error: " + label(el));
    });
    const out = document.createElement("pre");
    out.id = "REPORT_ID";
    out.textContent = JSON.stringify({equations: marked, problems: problems});
    document.body.appendChild(out);
  }
  window.addEventListener("load", function () {
    const mj = window.MathJax && window.MathJax.startup && window.MathJax.startup.promise;
    (mj || Promise.resolve()).then(report);
  });
})();
</script>""".replace("REPORT_ID", REPORT_ID)


class SiteHandler(http.server.SimpleHTTPRequestHandler):
    """Serves the built site quietly; adds the layout check to pages asked with the query."""

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (base's name)
        pass

    def do_GET(self) -> None:
        path, _, query = self.path.partition("?")
        if query != CHECK_QUERY:
            super().do_GET()
            return
        file = Path(self.translate_path(path))
        if file.is_dir():
            file = file / "index.html"
        if not file.is_file():
            self.send_error(404)
            return
        body = file.read_text(encoding="utf-8").replace("</body>", CHECK_SCRIPT + "</body>")
        data = body.encode()
        self.send_response(200)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)


def chromium_binary() -> str:
    """The Chromium executable; ``SystemExit`` saying how to install it if there is none."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    raise SystemExit("no Chromium found; on Debian: apt-get install chromium")


def run_chromium(binary: str, args: list[str], url: str, height: int) -> str:
    """Run headless Chromium once on ``url`` in a fresh profile; its standard output."""
    with tempfile.TemporaryDirectory(prefix="docs-chromium-") as profile:
        cmd = [binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
               "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--hide-scrollbars",
               f"--user-data-dir={profile}", f"--window-size={WIDTH},{height}",
               "--virtual-time-budget=15000", "--run-all-compositor-stages-before-draw",
               *args, url]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"chromium exited {done.returncode} on {url}: {done.stderr[-2000:]}")
    return done.stdout


def check_page(binary: str, url: str, height: int) -> dict[str, Any]:
    """The layout report the injected script writes into the page's DOM."""
    dom = run_chromium(binary, ["--dump-dom"], f"{url}?{CHECK_QUERY}", height)
    m = re.search(rf'<pre id="{REPORT_ID}">(.*?)</pre>', dom, re.S)
    if m is None:
        return {"equations": 0, "problems": ["the layout check did not run (no report in the DOM)"]}
    report: dict[str, Any] = json.loads(html.unescape(m.group(1)))
    return report


def build_site() -> None:
    """``mkdocs build --strict`` into ``SITE``, as CI builds it."""
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet",
           "-f", "docs/mkdocs.yml"]
    subprocess.run(cmd, check=True, cwd=ROOT)


def parse_pages(items: list[str] | None, height: int | None) -> dict[str, tuple[str, int]]:
    """``NAME=PATH`` arguments as name -> (path, height); the default pages when none are
    given. ``height`` overrides every page's height; given pages default to 2000 px."""
    if not items:
        return {name: (path, height or h) for name, (path, h) in PAGES.items()}
    pages = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or "/" in name or "#" in path or "?" in path:
            raise SystemExit("--pages takes NAME=PATH (NAME without '/', PATH without "
                             f"'#' or '?'), got {item!r}")
        pages[name] = (path.lstrip("/"), height or 2000)
    return pages


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "docs-screenshots",
                    help="folder for the PNGs (default: out/docs-screenshots)")
    ap.add_argument("--no-build", action="store_true", help="use the site already built")
    ap.add_argument("--height", type=int, default=None,
                    help="window height in pixels, how much of each page the PNG shows "
                         "(default: per page, 2000 for --pages)")
    ap.add_argument("--pages", nargs="+", metavar="NAME=PATH",
                    help="pages to shoot, as NAME=PATH under the site (default: "
                         + ", ".join(PAGES) + ")")
    args = ap.parse_args(argv)
    if args.height is not None and not 100 <= args.height <= 16000:
        ap.error(f"--height must lie in [100, 16000] pixels, got {args.height}")
    pages = parse_pages(args.pages, args.height)
    binary = chromium_binary()
    if not args.no_build:
        build_site()
    if not (SITE / "index.html").is_file():
        raise SystemExit(f"no built site in {SITE}; run without --no-build")
    args.out.mkdir(parents=True, exist_ok=True)
    handler = functools.partial(SiteHandler, directory=str(SITE))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    failed = False
    try:
        root_url = f"http://127.0.0.1:{server.server_address[1]}/"
        for name, (path, height) in pages.items():
            png = args.out / f"{name}.png"
            run_chromium(binary, [f"--screenshot={png}"], root_url + path, height)
            report = check_page(binary, root_url + path, height)
            problems = report["problems"]
            failed |= bool(problems)
            print(f"{name:18} {png}"
                  f"  {report['equations']} equations  "
                  f"{'OK' if not problems else str(len(problems)) + ' problems'}")
            for problem in problems:
                print(f"    {problem}")
    finally:
        server.shutdown()
        server.server_close()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
