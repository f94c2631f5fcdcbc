"""The main job: `stageid demo` runs all three workflows and leaves a full report."""

import json

import pytest

from stageid.cli.main import main
from stageid.models import load_model


@pytest.mark.study
@pytest.mark.slow
def test_demo_writes_report_metrics_and_models(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "P-558 Hankel-MAP" in printed and "maglev closed loop" in printed and "actuator hysteresis" in printed
    html = (out / "index.html").read_text()
    assert html.count("<img src='data:image/png;base64,") >= 8
    for title in ("P-558 3-DOF piezo stage", "Maglev stage", "Piezo actuator"):
        assert title in html
    assert f"<td>command</td><td>stageid demo --out {out}</td>" in html  # the report says what made it
    metrics = json.loads((out / "metrics.json").read_text())
    # the workflows' key results, with the issues' own acceptance levels
    assert metrics["p558/freq_error_diag_max_percent"] < 2.0
    assert metrics["p558/freq_error_coupling_max_percent"] < 1.0
    assert max(metrics["maglev/diag_error_20_300Hz_percent"]) < 1.0
    for found, true in zip(metrics["maglev/rhp_poles_rad_s"], metrics["maglev/rhp_poles_true_rad_s"]):
        assert abs(found - true) < 0.05 * true
    assert (
        metrics["hysteresis/model_error_percent_validation"]["modified-pi"]
        < metrics["hysteresis/model_error_percent_validation"]["pi"]
    )
    assert metrics["hysteresis/tracking_error_percent_fsr"]["modified-PI inverse"] < 2.0
    for name in (
        "p558_identified.json",
        "maglev_plant.json",
        "maglev_controller.json",
        "actuator_pi.json",
        "actuator_modified-pi.json",
    ):
        model = load_model(out / name)
        assert model.inputs and model.outputs
