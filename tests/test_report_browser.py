"""Reports render in a real headless browser and every embedded figure loads."""

import re
import shutil
import subprocess

import numpy as np
import pytest

from stageid.data import Experiment
from stageid.models import StateSpaceModel
from stageid.report import Report, model_report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")

_CHECK = """<script>
window.addEventListener('load', () => {
  const imgs = Array.from(document.images);
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
  document.body.setAttribute('data-images', ok + '/' + imgs.length);
});
</script></body>"""


def render_image_counts(html_path, tmp_path):
    """Load the page in headless Chromium; return (loaded, total) images as seen by the browser."""
    page = tmp_path / "check.html"
    page.write_text(html_path.read_text().replace("</body>", _CHECK))
    cmd = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--virtual-time-budget=10000",
        "--dump-dom",
        page.as_uri(),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    match = re.search(r'data-images="(\d+)/(\d+)"', proc.stdout)
    assert match, f"browser gave no result: {proc.stderr[-500:]}"
    return int(match.group(1)), int(match.group(2))


@pytest.fixture
def report_file(tmp_path):
    rng = np.random.default_rng(0)
    g = StateSpaceModel(
        [[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.5]], [[1.0, 0.0]], [[0.0]], dt=0.01, inputs=("u",), outputs=("y",)
    )
    u = rng.standard_normal((500, 1))
    exp = Experiment(u, g.simulate(u) + 0.01 * rng.standard_normal((500, 1)), 0.01, ("u",), ("y",), name="record")
    report, metrics = model_report(g, [exp])
    assert metrics["fit_percent/record/y"] > 90
    return report.write(tmp_path / "rep"), report.n_figures


def test_report_is_self_contained(report_file):
    path, n_figures = report_file
    text = path.read_text()
    assert n_figures == 3
    assert text.count("<img src='data:image/png;base64,") == n_figures
    assert "http://" not in text and "https://" not in text  # nothing external to fetch


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed (CI installs Debian's chromium in .ci/run)")
def test_every_figure_loads_in_headless_chromium(report_file, tmp_path):
    path, n_figures = report_file
    loaded, total = render_image_counts(path, tmp_path)
    assert total == n_figures and loaded == total


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed (CI installs Debian's chromium in .ci/run)")
def test_broken_figure_is_detected(tmp_path):
    # the check itself must be able to fail: one valid and one corrupt image
    r = Report("broken")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1])
    r.figure(fig, "good")
    html_text = r.to_html().replace(
        "</figure>", "</figure><figure><img src='data:image/png;base64,AAAA' alt='bad'></figure>", 1
    )
    path = tmp_path / "index.html"
    path.write_text(html_text)
    loaded, total = render_image_counts(path, tmp_path)
    assert (loaded, total) == (1, 2)
