"""`stageid report` and the identify verbs' `--report DIR`."""

import json

import numpy as np

from stageid.cli.main import main
from stageid.data.io import write_csv
from stageid.models import StateSpaceModel, save_model


def _record(tmp_path):
    rng = np.random.default_rng(3)
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=0.01, inputs=("u",), outputs=("y",))
    u = rng.standard_normal(3000)
    y = g.simulate(u[:, None])[:, 0] + 1e-3 * rng.standard_normal(3000)
    write_csv(tmp_path / "rec.csv", {"u": u, "y": y}, dt=0.01)
    return g


def test_report_command_writes_html_and_metrics(tmp_path):
    g = _record(tmp_path)
    save_model(g, tmp_path / "g.json")
    assert main(["report", str(tmp_path / "g.json"), str(tmp_path / "rec.csv"), "--out", str(tmp_path / "rep")]) == 0
    html = (tmp_path / "rep" / "index.html").read_text()
    assert html.count("<img src='data:image/png;base64,") == 3
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert metrics["fit_percent/rec.csv/y"] > 99.0  # the true model on its own record, 0.1 % noise


def test_identify_statespace_report(tmp_path):
    _record(tmp_path)
    rc = main(["identify", "statespace", str(tmp_path / "rec.csv"), "--inputs", "u", "--outputs", "y", "--order", "2",
               "--horizon", "10", "-o", str(tmp_path / "m.json"), "--report", str(tmp_path / "rep")])
    assert rc == 0 and (tmp_path / "m.json").exists()
    html = (tmp_path / "rep" / "index.html").read_text()
    assert "Hankel-MAP diagnostics" in html
    assert html.count("<img src='data:image/png;base64,") >= 4  # Bode, pole-zero, simulation, posterior bands


def test_identify_hysteresis_report(tmp_path):
    from stageid.data.io import write_csv as write
    from stageid.plants.piezo_actuator import EXPERIMENTS

    write(tmp_path / "ident.csv", EXPERIMENTS["decaying-triangle"](seed=0))
    rc = main(["identify", "hysteresis", str(tmp_path / "ident.csv"), "--input", "V", "--output", "y", "--model", "pi",
               "--operators", "10", "-o", str(tmp_path / "h.json"), "--report", str(tmp_path / "rep"), "--quiet"])
    assert rc == 0
    html = (tmp_path / "rep" / "index.html").read_text()
    assert html.count("<img src='data:image/png;base64,") == 1 and "Identification" in html
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert 0.0 < metrics["max_error_percent_range/ident.csv"] < 15.0  # classical PI on a non-PI actuator: a few %
