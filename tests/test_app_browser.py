"""stageid serve end to end in headless Chromium: open a measured FRF record, fit a model, see
its Bode plot, export it, and find the export equal to the shown command's output byte for byte.

The record is the AFM stage's measured FRF from the shared data folder; without that folder,
the z axis of the P-558 reference stage (``stageid plants``) stands in for it.
"""

import contextlib
import os
import shlex
import shutil
import subprocess
import sys

import pytest

from stageid.data import datasets

pytest.importorskip("starlette")
playwright = pytest.importorskip("playwright.sync_api")

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
AFM = None if datasets.SHARED_DATA is None else datasets.SHARED_DATA / "afm_piezo_stage_frf"
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine")


def _stageid(*args, cwd):
    subprocess.run([sys.executable, "-m", "stageid", *args], cwd=cwd, check=True, capture_output=True)


@pytest.fixture
def record(tmp_path):
    """(folder, record name, response name, fit settings) of the FRF the page opens."""
    if AFM is not None and (AFM / "FRF_data_current_stage2.mat").exists():
        settings = {"opt-order": "8", "opt-dt": "4e-5", "opt-fmin": "1", "opt-fmax": "2000"}
        return AFM, "FRF_data_current_stage2.mat", "frf.G_uz2stage", settings
    from stageid.data.io import read_table, write_csv

    folder = tmp_path / "records"
    folder.mkdir()
    _stageid("plants", "p558", "-o", "p558.json", cwd=tmp_path)
    _stageid("freqresp", "p558.json", "--fmin", "1", "--fmax", "200", "--n", "200", "-o", "fr.csv", cwd=tmp_path)
    table = read_table(tmp_path / "fr.csv", ts=1.0)
    write_csv(folder / "p558_z.csv", {n: table.column(n) for n in ("f_hz", "re_z_Z", "im_z_Z")})
    return folder, "p558_z.csv", "response", {"opt-order": "4", "opt-dt": "0.002"}


@pytest.fixture
def server(record, tmp_path):
    process = subprocess.Popen(
        [sys.executable, "-m", "stageid", "serve", str(record[0]), "--port", "0"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        text=True,
    )
    address = process.stdout.readline().split()[2]
    yield address
    process.terminate()
    process.wait(timeout=10)


def _shoot(page, name, tmp_path):
    """A screenshot of a board; into $STAGEID_SCREENSHOTS too when set (the docs' images)."""
    page.screenshot(path=str(tmp_path / f"{name}.png"), full_page=True)
    folder = os.environ.get("STAGEID_SCREENSHOTS")
    if folder:
        page.screenshot(path=os.path.join(folder, f"{name}.png"), full_page=True)


def _fetch(page, link):
    """The bytes behind a download link, fetched by the page itself (its session cookie)."""
    script = "async a => { const r = await fetch(a.href); return [r.status, Array.from(new Uint8Array(await r.arrayBuffer()))]; }"
    status, data = page.eval_on_selector(link, script)
    assert status == 200, bytes(data)
    return bytes(data)


def test_fit_bode_and_export_in_the_browser(server, record, tmp_path):
    folder, name, response, settings = record
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        context = browser.new_context(viewport={"width": 1200, "height": 900})
        page = context.new_page()
        page.goto(server)
        page.select_option("#record", f"folder:{name}")
        page.click("#inspect")
        page.wait_for_selector("#frd-settings:not([hidden])")
        page.select_option("#response", response)
        page.click("#prepare")
        page.wait_for_selector("#data-figures svg")
        data_file = page.get_attribute("#data-download", "download")
        (tmp_path / data_file).write_bytes(_fetch(page, "#data-download"))
        _shoot(page, "serve-data", tmp_path)

        page.click("#tab-estimate")
        page.select_option("#estimate-method", "frd")
        for field, value in settings.items():
            page.fill(f"#{field}", value)
        page.click("#run-estimate")
        page.wait_for_selector("#estimate-figures svg", timeout=180_000)
        assert page.inner_text("#error") == ""
        command = page.inner_text("#estimate-cli")
        python = page.inner_text("#estimate-python")
        assert command.startswith(f"stageid identify frd {data_file} --order {settings['opt-order']}")
        _shoot(page, "serve-estimate", tmp_path)

        page.click("#tab-export")
        page.select_option("#export-format", "json")
        page.click("#run-export")
        page.wait_for_selector("#download:not([hidden])")
        exported = _fetch(page, "#download")
        _shoot(page, "serve-export", tmp_path)

        other_tab = context.new_page()  # same browser, same cookies: a session of its own
        other_tab.goto(server)
        other_tab.wait_for_function("document.querySelector('#record').options.length > 0")
        assert other_tab.eval_on_selector("#export-model", "s => s.options.length") == 0
        assert page.eval_on_selector("#export-model", "s => s.options.length") == 1
        browser.close()

    args = shlex.split(command)
    subprocess.run([sys.executable, "-m", "stageid", *args[1:]], cwd=tmp_path, check=True, capture_output=True)
    model_file = tmp_path / args[args.index("-o") + 1]
    assert exported == model_file.read_bytes()
    model_file.unlink()  # the Python call shown beside the command writes the same file
    with contextlib.chdir(tmp_path):
        exec(python, {})
    assert exported == model_file.read_bytes()
