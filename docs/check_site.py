"""Open the built documentation in headless Chromium, as a reader would, and check it.

    python docs/check_site.py docs/_build/html

The site is served on a loopback port; every page a reader starts from (the landing page, the
guides, the tutorials, the gallery and its examples, the API index, the CLI page) is loaded and
must raise no JavaScript error, log no console error and load every image; the search page must
list the API page of ``HankelMAP`` for the query ``HankelMAP``. Exit code 0 when all pass, 1
otherwise (one line per failure), 2 when Chromium is missing.
"""

from __future__ import annotations

import functools
import http.server
import io
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

# Injected at the top of every page: records console errors, uncaught errors and failed loads
# (images, scripts, styles) before the page's own scripts run, and the images' state at load.
PROBE = b"""<script>
window.__problems = [];
const __error = console.error;
console.error = (...a) => { window.__problems.push('console: ' + a.join(' ')); __error(...a); };
window.addEventListener('error', e => {
  const t = e.target;
  window.__problems.push(t && t !== window ? 'failed to load: ' + (t.src || t.href) : 'error: ' + e.message);
}, true);
window.addEventListener('unhandledrejection', e => window.__problems.push('rejection: ' + e.reason));
window.addEventListener('load', () => setTimeout(() => {
  const imgs = Array.from(document.images);
  const bad = imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src);
  document.body.setAttribute('data-images', (imgs.length - bad.length) + '/' + imgs.length);
  document.body.setAttribute('data-problems', JSON.stringify(window.__problems.concat(bad.map(s => 'image: ' + s))));
}, 1500));
</script>"""

SEARCH_TARGET = "api/generated/stageid.subspace.HankelMAP.html"


class ProbingHandler(http.server.SimpleHTTPRequestHandler):
    """Serves the site, with :data:`PROBE` inserted after ``<head>`` of every HTML page."""

    def send_head(self):
        path = Path(self.translate_path(self.path))
        if path.is_dir():
            path = path / "index.html"
        if path.suffix != ".html" or not path.is_file():
            return super().send_head()
        body = path.read_bytes().replace(b"<head>", b"<head>" + PROBE, 1)
        self.send_response(200)
        self.send_header("Content-Type", "text/html; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        return io.BytesIO(body)

    def log_message(self, *args) -> None:  # quiet: failures are reported by the checks
        pass


def pages(site: Path) -> list[str]:
    """The pages a reader starts from: every page outside the generated API stubs."""
    found = sorted(p.relative_to(site).as_posix() for p in site.rglob("*.html"))
    skip = ("api/generated/", "_static/", "_modules/", "genindex", "py-modindex", "search.html", "sg_execution_times")
    return [p for p in found if not any(s in p for s in skip)]


def dump(chromium: str, url: str, profile: Path) -> str:
    """The page's DOM after load and the probe's delay, as headless Chromium sees it."""
    cmd = [
        chromium,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        "--virtual-time-budget=8000",
        "--dump-dom",
        url,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout


def check_page(chromium: str, base: str, page: str, profile: Path) -> list[str]:
    dom = dump(chromium, f"{base}/{page}", profile)
    images = re.search(r'data-images="(\d+)/(\d+)"', dom)
    problems = re.search(r'data-problems="([^"]*)"', dom)
    if not images or not problems:
        return [f"{page}: the page did not finish loading"]
    text = problems.group(1).replace("&quot;", '"')
    found = re.findall(r'"((?:[^"\\]|\\.)*)"', text)
    return [f"{page}: {item}" for item in found]


def check_search(chromium: str, base: str, profile: Path) -> list[str]:
    dom = dump(chromium, f"{base}/search.html?q=HankelMAP", profile)
    links = re.findall(r'<li[^>]*>\s*<a href="([^"?#]+)', dom)
    if SEARCH_TARGET not in links:
        return [f"search for HankelMAP: {SEARCH_TARGET} not among the results {links[:5]}"]
    return []


def main(argv: list[str]) -> int:
    site = Path(argv[1] if len(argv) > 1 else "docs/_build/html").resolve()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if chromium is None:
        print("check_site: no Chromium on this machine", file=sys.stderr)
        return 2
    if not (site / "index.html").is_file():
        print(f"check_site: no built site in {site}", file=sys.stderr)
        return 1
    handler = functools.partial(ProbingHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}"
    failures: list[str] = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            todo = pages(site)
            for page in todo:
                failures += check_page(chromium, base, page, Path(tmp) / "profile")
            failures += check_search(chromium, base, Path(tmp) / "profile")
    finally:
        server.shutdown()
    for line in failures:
        print(f"check_site: {line}", file=sys.stderr)
    print(f"check_site: {len(todo)} pages and the search checked, {len(failures)} problems")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
