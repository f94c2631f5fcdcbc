"""Notebook display: a short repr and a table + inline SVG for models, FRDs, results and reports."""

import re

import numpy as np
import pytest

from stageid import display
from stageid.batch import Outcome
from stageid.data import Experiment
from stageid.frf import FrequencyResponse
from stageid.hysteresis import ModifiedPIModel, PIIdentifier, PIModel, PreisachModel
from stageid.models import StateSpaceModel
from stageid.subspace import HankelMAP
from stageid.validation import whiteness_test

# a lightly damped pair at 0.2 rad/sample: the model and its records are made for these tests
G = StateSpaceModel(
    [[1.6, -0.8], [1.0, 0.0]], [[1.0], [0.0]], [[0.1, 0.05]], [[0.0]], dt=0.001, inputs=["u"], outputs=["y"]
)


def record(seed: int, n: int = 3000) -> Experiment:
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 1))
    return Experiment(u, G.simulate(u) + 1e-3 * rng.standard_normal((n, 1)), 0.001, ("u",), ("y",))


@pytest.fixture(scope="module")
def hankel_result():
    return HankelMAP(horizon=10, order=2).fit(record(0))


def test_hankel_result_repr_is_one_short_line(hankel_result):
    # the dataclass repr printed every array of the posterior (tens of kilobytes)
    text = repr(hankel_result)
    assert len(text) < 200 and "\n" not in text
    assert text.startswith("HankelMAPResult(model=StateSpaceModel(2 states, 1x1, 0.001 s)")


def test_result_html_has_a_table_and_a_bode_figure_with_its_band(hankel_result):
    html = hankel_result._repr_html_()
    assert html.count("<table") == 1 and html.count("<svg") == 1
    assert ">horizon<" in html and "frequency [Hz]" in html
    assert "fill-opacity: 0.25" in html  # the +-2 std band is drawn
    assert len(html) < 150_000  # a notebook cell, not a report


def test_frequency_response_html_draws_the_data_with_its_std():
    f = np.geomspace(1.0, 400.0, 500)
    frd = FrequencyResponse(f, G.frequency_response(f), std=np.full((500, 1, 1), 0.01), inputs=("u",), outputs=("y",))
    html = frd._repr_html_()
    assert "<svg" in html and "500, 1-400 Hz" in html and "std" in html
    # the 500 lines are thinned to a thumbnail's worth of points
    path_points = max(len(re.findall(r"L [\d.]+ [\d.]+", p)) for p in re.findall(r'<path d="([^"]*)"', html))
    assert path_points <= 2 * display.N_POINTS + 4


def test_hysteresis_models_show_their_major_loop():
    pi = PIModel(r=[0.0, 1.0, 2.0], weights=[1.0, 0.5, 0.25], input_limits=(-3.0, 3.0))
    preisach = PreisachModel(input_range=(-1.0, 1.0), weights=np.full(10, 0.1))
    for model in (pi, preisach):
        text, html = repr(model), model._repr_html_()
        assert len(text) < 200 and "[" not in text  # no arrays
        assert "major loop" in html and "<table" in html
    assert "operators=3" in repr(pi) and "levels=4" in repr(preisach)


def test_hysteresis_fit_repr_names_model_and_errors():
    rng = np.random.default_rng(1)
    u = np.concatenate([np.linspace(0, 2, 200), np.linspace(2, -2, 400), np.linspace(-2, 2, 400)])
    y = PIModel(r=[0.0, 0.5, 1.0], weights=[1.0, 0.3, 0.2]).simulate(u)[:, 0] + 1e-4 * rng.standard_normal(u.size)
    fit = PIIdentifier("modified-pi", n_operators=3, input_warp=False).fit((u, y))
    assert isinstance(fit.model, ModifiedPIModel)
    text = repr(fit)
    assert text.startswith("HysteresisResult(model=ModifiedPIModel(") and "max error=" in text and len(text) < 300
    assert "<svg" in fit._repr_html_()


def test_validation_and_batch_outcomes_are_tables_without_figures():
    test = whiteness_test([np.random.default_rng(2).standard_normal(500)])
    assert repr(test).startswith("CorrelationTest(passed=") and "lags" in repr(test)
    assert "<table" in test._repr_html_() and "<svg" not in test._repr_html_()
    failed = Outcome("unit4", "failed", 0.002, "tcp://w", "file 'unit4.csv' does not exist.")
    assert "error=file 'unit4.csv' does not exist." in repr(failed)
    assert "&#x27;unit4.csv&#x27;" in failed._repr_html_()  # escaped, never raw markup


def test_a_report_shows_its_content_inline():
    from stageid.report import model_report

    report, _ = model_report(G, [record(3, n=1000)])
    text = repr(report)
    assert text.startswith("Report(title=") and "figures=" in text and len(text) < 200
    html = report._repr_html_()
    assert "<img src='data:image/png;base64," in html and "<table>" in html
    assert "<style>" not in html and "<body>" not in html  # a fragment: the notebook keeps its own style


def test_every_described_class_uses_the_display_module():
    import stageid.batch
    import stageid.closedloop
    import stageid.frf
    import stageid.hysteresis
    import stageid.models
    import stageid.report
    import stageid.subspace
    import stageid.validation.residuals

    packages = [stageid.batch, stageid.closedloop, stageid.frf, stageid.hysteresis, stageid.models, stageid.subspace]
    packages.append(stageid.report)
    packages.append(stageid.validation.residuals)
    found = {}
    for package in packages:
        for name in display.FACTS:
            if hasattr(package, name):
                found[name] = getattr(package, name)
    assert set(found) == set(display.FACTS)
    for name, cls in found.items():
        # its own or a base class's (the hysteresis results share theirs)
        owner = next((c for c in cls.__mro__ if "_repr_html_" in vars(c)), None)
        assert owner is not None and owner.__module__.startswith("stageid."), name


@pytest.mark.slow  # starts a Jupyter kernel: about 15 s
def test_a_notebook_shows_the_rich_display():
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    cells = [
        "import numpy as np\nfrom stageid.models import StateSpaceModel\nfrom stageid.data import Experiment\n"
        "from stageid.subspace import HankelMAP",
        "g = StateSpaceModel([[1.6, -0.8], [1.0, 0.0]], [[1.0], [0.0]], [[0.1, 0.05]], [[0.0]], dt=0.001)\n"
        "rng = np.random.default_rng(0)\nu = rng.standard_normal((3000, 1))\n"
        "result = HankelMAP(horizon=10, order=2).fit(Experiment(u, g.simulate(u), 0.001))",
        "result",
        "result.model",
    ]
    notebook = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    notebook.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbclient.NotebookClient(notebook, timeout=120, kernel_name="python3").execute()
    for cell, title in zip(notebook.cells[2:], ("HankelMAPResult", "StateSpaceModel")):
        data = next(out for out in cell.outputs if out["output_type"] == "execute_result")["data"]
        assert f"<b>{title}</b>" in data["text/html"] and "<svg" in data["text/html"]
        assert data["text/plain"].startswith(title) and len(data["text/plain"]) < 200
