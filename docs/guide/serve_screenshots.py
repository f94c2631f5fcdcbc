"""Screenshots of the four boards of ``stageid serve`` for serve.md (run: python serve_screenshots.py).

Uses the P-558 reference stage's z axis (a chirp to identify, a random record to compare on),
headless Chromium through playwright, and writes docs/guide/img/serve-*.png.
"""

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from playwright.sync_api import sync_playwright

IMG = Path(__file__).with_name("img")


def stageid(*args, cwd):
    subprocess.run([sys.executable, "-m", "stageid", *args], cwd=cwd, check=True, capture_output=True)


def make_data_set(page, record):
    page.click("#tab-data")
    page.select_option("#record", f"folder:{record}")
    page.click("#inspect")
    page.wait_for_selector("#time-settings:not([hidden])")
    page.select_option("#inputs", ["Z"])
    page.select_option("#outputs", ["z"])
    page.select_option("#detrend", "constant")
    page.click("#prepare")
    page.wait_for_function("document.querySelector('#record-info').textContent.includes('made')")


def run(page, button, shown, shot=None):
    """Click ``button``, wait until ``shown`` appears, and save the page as ``shot`` when given."""
    page.click(button)
    page.wait_for_selector(shown, timeout=300_000)
    if shot:
        page.screenshot(path=str(IMG / f"{shot}.png"), full_page=True)


def main():
    folder = Path(tempfile.mkdtemp())
    stageid("plants", "p558", "--experiment", "chirp-z", "-o", "chirp_z.csv", cwd=folder)
    stageid("plants", "p558", "--experiment", "random-z", "--seed", "1", "-o", "random_z.csv", cwd=folder)
    server = subprocess.Popen(
        [sys.executable, "-m", "stageid", "serve", str(folder), "--port", "0"], stdout=subprocess.PIPE, text=True
    )
    address = server.stdout.readline().split()[2]
    try:
        with sync_playwright() as p:
            chromium = shutil.which("chromium") or shutil.which("google-chrome")
            browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
            page = browser.new_page(viewport={"width": 1100, "height": 800})
            page.goto(address)
            make_data_set(page, "chirp_z.csv")
            page.screenshot(path=str(IMG / "serve-data.png"), full_page=True)
            page.click("#tab-estimate")
            page.select_option("#estimate-method", "statespace")
            page.fill("#opt-horizon", "30")
            run(page, "#run-order", "#order-figures svg")
            page.fill("#opt-ss-order", "7")
            run(page, "#run-estimate", "#estimate-figures svg", "serve-estimate")
            make_data_set(page, "random_z.csv")
            page.click("#tab-compare")
            held_out = page.eval_on_selector("#compare-data", "s => s.options[s.options.length - 1].value")
            page.select_option("#compare-data", held_out)
            run(page, "#run-compare", "#compare-figures svg", "serve-compare")
            page.click("#tab-export")
            page.select_option("#export-format", "c")
            page.fill("#export-prefix", "stage")
            run(page, "#run-export", "#download:not([hidden])", "serve-export")
            browser.close()
    finally:
        server.terminate()
        server.wait(timeout=10)
        shutil.rmtree(folder)


if __name__ == "__main__":
    main()
