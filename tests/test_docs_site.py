"""The documentation's browser check finds what a reader would see: errors and broken images."""

import base64
import functools
import http.server
import importlib.util
import shutil
import threading
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed")

# a 1x1 PNG
PIXEL = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAQAAAC1HAwCAAAAC0lEQVR42mNkYAAAAAYAAjCB0C8AAAAASUVORK5CYII=")


def load_checker():
    path = Path(__file__).resolve().parents[1] / "docs" / "check_site.py"
    spec = importlib.util.spec_from_file_location("check_site", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def served(tmp_path):
    """A two-page site served with the checker's probe: one good page, one broken."""
    checker = load_checker()
    site = tmp_path / "site"
    site.mkdir()
    (site / "pixel.png").write_bytes(PIXEL)
    (site / "good.html").write_text("<html><head></head><body><img src='pixel.png'></body></html>")
    (site / "broken.html").write_text(
        "<html><head></head><body><img src='missing.png'><script>console.error('boom')</script></body></html>"
    )
    handler = functools.partial(checker.ProbingHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield checker, f"http://127.0.0.1:{server.server_address[1]}", tmp_path / "profile"
    server.shutdown()


def test_a_clean_page_passes_and_a_broken_one_reports_its_error_and_image(served):
    checker, base, profile = served
    assert checker.check_page(CHROMIUM, base, "good.html", profile) == []
    problems = checker.check_page(CHROMIUM, base, "broken.html", profile)
    assert any("console: boom" in p for p in problems)
    assert any("missing.png" in p for p in problems)


def test_pages_a_reader_starts_from_leave_out_generated_stubs(tmp_path):
    checker = load_checker()
    for page in ("index.html", "api/index.html", "api/generated/stageid.X.html", "_static/x.html", "search.html"):
        (tmp_path / page).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / page).write_text("<html></html>")
    assert checker.pages(tmp_path) == ["api/index.html", "index.html"]
