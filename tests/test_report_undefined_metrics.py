"""Reports on data with a constant channel, atomic report folders and warning-free log plots."""

import io
import json
import warnings

import numpy as np
import pytest

from stageid.data import Experiment
from stageid.models import StateSpaceModel
from stageid.report import Report, model_report, write_metrics, write_report_folder
from stageid.validation import fit_percent


def _model():
    return StateSpaceModel(
        [[0.9, 0.2], [-0.2, 0.9]],
        [[1.0], [0.0]],
        [[0.5, 0.1], [0.0, 0.0]],
        [[0.0], [0.0]],
        dt=0.01,
        inputs=("u",),
        outputs=("y", "flat"),
    )


def _experiment(n=400):
    u = np.random.default_rng(4).standard_normal((n, 1))
    y = _model().simulate(u)
    y[:, 1] = 1.5  # a sensor that does not move (and an offset the model cannot produce)
    return Experiment(u, y, 0.01, input_names=("u",), output_names=("y", "flat"), name="rec")


def test_fit_percent_of_a_constant_channel_is_nan_not_minus_inf():
    y = np.column_stack([np.full(50, 1.5), np.sin(np.arange(50.0))])
    fit = fit_percent(y, np.zeros_like(y))
    assert np.isnan(fit[0]) and np.isfinite(fit[1])
    assert np.isnan(fit_percent(np.full(10, 0.1 + 0.2), np.full(10, 0.3))[0])  # mean rounding is no variation


def test_lti_report_with_constant_output_completes_with_null_and_na(tmp_path):
    report, metrics = model_report(_model(), [_experiment()])
    assert np.isnan(metrics["fit_percent/rec/flat"]) and metrics["fit_percent/rec/y"] > 99.0
    path = write_report_folder(tmp_path / "rep", report, metrics)
    written = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert written["fit_percent/rec/flat"] is None  # strict JSON: undefined is null, never -inf
    assert "-Infinity" not in (tmp_path / "rep" / "metrics.json").read_text()
    html = path.read_text()
    assert "<td>n/a</td>" in html and "does not move" in html


def test_hysteresis_report_with_constant_output_completes(tmp_path):
    from stageid.hysteresis import PIModel

    model = PIModel(r=[0.0, 0.5], weights=[1.0, 0.5])
    u = np.sin(np.linspace(0, 6, 300))[:, None]
    exp = Experiment(u, np.full((300, 1), 1.5), 0.01, input_names=("V",), output_names=("y",), name="flat")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the old code divided by a zero range (RuntimeWarning)
        report, metrics = model_report(model, [exp])
        write_report_folder(tmp_path / "rep", report, metrics)
    assert json.loads((tmp_path / "rep" / "metrics.json").read_text()) == {
        "max_error_percent_range/flat": None,
        "units": {"max_error_percent_range/flat": "% of the output's range"},
    }


def test_write_metrics_writes_non_finite_as_null(tmp_path):
    write_metrics(tmp_path, {"a": float("-inf"), "b": [1.0, float("nan")], "c": np.float64("inf"), "d": 2.5})
    written = json.loads((tmp_path / "metrics.json").read_text())
    assert written == {"a": None, "b": [1.0, None], "c": None, "d": 2.5, "units": {}}  # no name says a unit


def test_report_folder_is_all_or_nothing(tmp_path):
    report = Report("x")
    with pytest.raises(TypeError):
        write_report_folder(tmp_path / "rep", report, {"bad": object()})  # metrics fail after the HTML rendered
    assert list(tmp_path.iterdir()) == []  # no folder, no index.html, no temporary folder
    write_report_folder(tmp_path / "rep", report, {"fit": 1.0})
    assert sorted(p.name for p in (tmp_path / "rep").iterdir()) == ["index.html", "metrics.json"]
    write_report_folder(tmp_path / "rep", Report("second"), {"fit": 2.0})  # an existing folder is updated
    assert "second" in (tmp_path / "rep" / "index.html").read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["rep"]


def test_report_folder_needs_an_existing_parent(tmp_path):
    from stageid import DataError

    with pytest.raises(DataError, match=r"directory '.*nodir' does not exist"):
        write_report_folder(tmp_path / "nodir" / "rep", Report("x"))


def test_log_plots_of_zero_responses_draw_without_warnings():
    from stageid.plots import bode_figure
    from stageid.plots.subspace import error_curve

    f = np.geomspace(1.0, 100.0, 50)
    H = np.ones((50, 2, 2), dtype=complex)
    H[:, :, 1] = 0.0  # an input that did not move: its identified response is exactly zero
    bands = {"model": (np.zeros((50, 2, 2)), np.abs(H) * 2)}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib's "cannot be log-scaled" warnings fail here
        for fig in (
            bode_figure(f, {"model": H}, ["a", "b"], ["y1", "y2"], bands=bands),
            error_curve([1, 2, 3], {"err": [0.0, -1.0, 2.0]}, xlabel="order"),
        ):
            fig.savefig(io.BytesIO(), format="png")
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    zero_notes = [t for ax in bode_figure(f, {"model": H}, ["a", "b"], ["y1", "y2"]).axes for t in ax.texts]
    assert len(zero_notes) == 2 and texts == []  # one note per all-zero magnitude axis
