"""Open HTML pages in a real headless browser and check they render.

    python docs/check_pages.py PAGE.html [PAGE.html ...] [--site DIR] [--browser chromium]

Each page is served over HTTP from its site's root (``--site``, default the page's own
folder; ``http.server`` in this process, so relative links and scripts resolve as they do
on a web server) and opened by the
browser inside a same-origin frame of a probe page. Once the page has loaded, the probe
records, for every ``<img>`` of the page, whether it loaded (``complete`` with a natural
width above 0), and the length of the page's visible text; the browser prints the DOM
(``--dump-dom``) and this script reads the record from it. A page fails when it did not
load, when one of its images did not load, or when it shows fewer than ``--min-text``
characters of text (a blank page). Exit status 1 if any page failed; each page gets a
line saying why.

The browser is Debian's ``chromium`` (``apt-get install chromium``) or any Chrome-like
binary given with ``--browser``.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import json
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

#: the probe: loads the page in a frame, waits for it and its images, writes the record
PROBE = """<!doctype html><html><head><meta charset="utf-8"><title>probe</title></head>
<body><pre id="record">pending</pre>
<iframe id="page" src="{src}" style="width:1200px;height:900px"></iframe>
<script>
function check() {{
  const rec = document.getElementById("record");
  let doc;
  try {{ doc = document.getElementById("page").contentDocument; }}
  catch (e) {{ rec.textContent = JSON.stringify({{error: "frame not readable: " + e}}); return; }}
  if (!doc || !doc.body) {{ rec.textContent = JSON.stringify({{error: "no document"}}); return; }}
  const images = Array.from(doc.images).map(im => ({{
      src: im.currentSrc || im.src, loaded: im.complete && im.naturalWidth > 0}}));
  rec.textContent = JSON.stringify({{title: doc.title, url: doc.location.href,
      text: (doc.body.innerText || "").trim().length, images: images}});
}}
document.getElementById("page").addEventListener("load", () => setTimeout(check, 1500));
</script></body></html>
"""
RECORD = re.compile(r'<pre id="record">(.*?)</pre>', re.S)


@dataclass
class PageCheck:
    """What the browser saw of one page."""

    page: Path
    ok: bool
    reason: str
    images: int = 0
    text: int = 0


def find_browser(name: str | None = None) -> str:
    """The browser binary: ``name`` if given, else the first of chromium, chromium-browser,
    google-chrome on the PATH."""
    for candidate in ([name] if name else ["chromium", "chromium-browser", "google-chrome"]):
        path = shutil.which(candidate)
        if path:
            return path
    tried = name or "chromium, chromium-browser, google-chrome"
    raise FileNotFoundError(f"no browser found ({tried}): apt-get install chromium, or pass "
                            "--browser")


def _serve(root: Path) -> tuple[http.server.ThreadingHTTPServer, int]:
    handler = functools.partial(_QuietHandler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, server.server_address[1]


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # the check prints its own lines
        pass


def check_page(page: Path, browser: str, min_text: int = 200, timeout: float = 120.0,
               site: Path | None = None) -> PageCheck:
    """Serve ``site`` (default: ``page``'s folder; give the site's root when the page
    links to files above its folder, as a page of a Sphinx build does), open the probe in
    ``browser``, read the record."""
    page = page.resolve()
    if not page.is_file():
        return PageCheck(page, False, "no such file")
    site = (site or page.parent).resolve()
    if not page.is_relative_to(site):
        return PageCheck(page, False, f"not inside the served site {site}")
    with tempfile.TemporaryDirectory(prefix="rbbench-pages-") as tmp:
        root = Path(tmp)
        (root / "site").symlink_to(site, target_is_directory=True)
        rel = page.relative_to(site).as_posix()
        (root / "probe.html").write_text(PROBE.format(src=f"site/{rel}"))
        server, port = _serve(root)
        try:
            out = subprocess.run(
                [browser, "--headless", "--no-sandbox", "--disable-gpu",
                 "--user-data-dir=" + str(root / "profile"), "--virtual-time-budget=15000",
                 "--run-all-compositor-stages-before-draw", "--dump-dom",
                 f"http://127.0.0.1:{port}/probe.html"],
                capture_output=True, text=True, timeout=timeout)
        finally:
            server.shutdown()
            server.server_close()
    match = RECORD.search(out.stdout)
    if out.returncode != 0 or not match:
        return PageCheck(page, False, f"the browser printed no record (exit {out.returncode}: "
                         f"{out.stderr.strip()[-300:]})")
    try:
        record = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    except json.JSONDecodeError:
        return PageCheck(page, False, f"the page did not finish loading ({match.group(1)[:80]})")
    if "error" in record:
        return PageCheck(page, False, record["error"])
    broken = [im["src"] for im in record["images"] if not im["loaded"]]
    n_img, n_text = len(record["images"]), int(record["text"])
    if broken:
        return PageCheck(page, False, f"{len(broken)} of {n_img} images did not load: "
                         + ", ".join(broken[:5]), n_img, n_text)
    if n_text < min_text:
        return PageCheck(page, False, f"blank: {n_text} characters of text (< {min_text})",
                         n_img, n_text)
    return PageCheck(page, True, "ok", n_img, n_text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pages", nargs="+", type=Path, help="HTML files to open")
    ap.add_argument("--browser", help="browser binary (default: chromium, chromium-browser "
                    "or google-chrome, the first on the PATH)")
    ap.add_argument("--site", type=Path, default=None,
                    help="the folder served as the site's root (default: each page's own "
                    "folder); the root of a Sphinx build for its pages")
    ap.add_argument("--min-text", type=int, default=200,
                    help="characters of visible text below which a page counts as blank "
                    "(default: 200)")
    args = ap.parse_args(argv)
    try:
        browser = find_browser(args.browser)
    except FileNotFoundError as err:
        print(err, file=sys.stderr)
        return 2
    failed = 0
    for page in args.pages:
        res = check_page(page, browser, args.min_text, site=args.site)
        failed += not res.ok
        print(f"{'ok  ' if res.ok else 'FAIL'} {page}: {res.reason} ({res.images} images, "
              f"{res.text} characters of text)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
