"""The hysteresis report draws the band the weights' uncertainty puts on the loop."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.collections import PolyCollection

from stageid.cli.main import main
from stageid.data import Experiment
from stageid.data.io import write_csv
from stageid.hysteresis import PIIdentifier, PIModel
from stageid.report.model_report import hysteresis_model_report
from stageid.signals import decaying_triangle

U = decaying_triangle(1.0, 8, 1e-3, amplitude=10.0)
TRUE = PIModel(r=np.arange(8) * 10.0 / 8, weights=np.array([1.0, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05, 0.05]))
Y = TRUE.simulate(U).reshape(-1) + 0.01 * 48.0 * np.random.default_rng(0).standard_normal(U.size)


def _fit():
    return PIIdentifier("pi", n_operators=8, initial_state="zero", weight_uncertainty="sandwich").fit((U, Y))


def test_the_loop_band_is_drawn_from_the_weight_covariance(drawn):
    fit = _fit()
    exp = Experiment(U[:, None], Y[:, None], 1e-3, input_names=fit.model.inputs, output_names=fit.model.outputs)
    report, metrics = hysteresis_model_report(fit.model, [exp], uncertainty=fit.weight_uncertainty)
    y_hat, std = fit.weight_uncertainty.output_band(fit.model, U, 1e-3)
    assert std.max() > 0
    ((fig, caption),) = drawn
    assert "weights' uncertainty" in caption
    loop, error = fig.axes
    # left: the model's loop with the band's two edges at y_hat -+ 1.96 std
    edges = [ln.get_ydata() for ln in loop.get_lines() if ln.get_color() == "C1"]
    assert len(edges) == 2
    np.testing.assert_allclose(sorted(edges, key=np.mean)[1], y_hat + 1.96 * std, rtol=1e-12)
    np.testing.assert_allclose(sorted(edges, key=np.mean)[0], y_hat - 1.96 * std, rtol=1e-12)
    # right: the shaded band of +-1.96 std in % of the output's range, around the error
    (band,) = [c for c in error.collections if isinstance(c, PolyCollection)]
    top = band.get_paths()[0].vertices[:, 1].max()
    half = 100 * 1.96 * std / np.ptp(Y)
    np.testing.assert_allclose(top, half.max(), rtol=1e-9)
    assert metrics["loop_band/max_half_width_percent_range/0"] == pytest.approx(half.max())
    assert metrics["loop_band/median_half_width_percent_range/0"] == pytest.approx(np.median(half))
    inside = np.mean(np.abs(Y - y_hat) <= 1.96 * std)
    assert metrics["loop_band/error_inside_percent/0"] == pytest.approx(100 * inside)
    assert "Uncertainty of the weights" in report.to_html()


def test_no_band_without_the_uncertainty(drawn):
    fit = _fit()
    exp = Experiment(U[:, None], Y[:, None], 1e-3, input_names=fit.model.inputs, output_names=fit.model.outputs)
    report, metrics = hysteresis_model_report(fit.model, [exp])
    ((fig, _),) = drawn
    assert not any(isinstance(c, PolyCollection) for ax in fig.axes for c in ax.collections)
    assert not any(k.startswith("loop_band/") for k in metrics)
    assert "Uncertainty of the weights" not in report.to_html()


def test_identify_hysteresis_report_draws_the_band(tmp_path, drawn):
    write_csv(tmp_path / "r.csv", {"V": U, "y": Y}, dt=1e-3)
    args = ["identify", "hysteresis", str(tmp_path / "r.csv"), "--input", "V", "--output", "y", "--model", "pi"]
    args += ["--operators", "8", "--initial-state", "zero", "-o", str(tmp_path / "m.json"), "--quiet"]
    assert main([*args, "--report", str(tmp_path / "rep")]) == 0
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    # the band of the CLI's fit is the same as the library's on the same record
    y_hat, std = _fit().weight_uncertainty.output_band(_fit().model, U, 1e-3)
    want = 100 * 1.96 * std.max() / np.ptp(Y)
    assert metrics["loop_band/max_half_width_percent_range/r.csv"] == pytest.approx(want, rel=1e-6)
    assert any(isinstance(c, PolyCollection) for fig, _ in drawn for ax in fig.axes for c in ax.collections)
    assert "Uncertainty of the weights" in (tmp_path / "rep" / "index.html").read_text()
