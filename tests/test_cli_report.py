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


def test_identify_closed_loop_report(tmp_path):
    # an unstable first-order plant under a proportional controller, one reference
    from stageid.models import feedback

    rng = np.random.default_rng(5)
    G = StateSpaceModel([[1.02]], [[0.05]], [[1.0]], [[0.0]], dt=0.001, inputs=("u",), outputs=("y",))
    K = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], dt=0.001, inputs=("e",), outputs=("u",))
    save_model(K, tmp_path / "K.json")
    r = rng.standard_normal(4000)
    r[:100] = 0.0  # the loop starts at rest
    yu = feedback(G, K).simulate(r[:, None])
    write_csv(tmp_path / "exp.csv", {"r_y": r, "y": yu[:, 0] + 1e-5 * rng.standard_normal(4000), "u": yu[:, 1]}, dt=0.001)
    rc = main(["identify", "closed-loop", str(tmp_path / "exp.csv"), "--references", "r_y", "--outputs", "y",
               "--controller", str(tmp_path / "K.json"), "--structure", "full", "--band", "1:100",
               "-o", str(tmp_path / "G.json"), "--report", str(tmp_path / "rep")])
    assert rc == 0
    html = (tmp_path / "rep" / "index.html").read_text()
    assert html.count("<img src='data:image/png;base64,") == 4
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    fits = [v for k, v in metrics.items() if k.startswith("reclosed_fit_percent/") and k.endswith("/y")]
    assert len(fits) == 1 and fits[0] > 99.0  # the identified plant re-closed with K reproduces y
    s_true = np.log(1.02) / 0.001
    assert min(abs(p - s_true) for p in metrics["unstable_poles_rad_s"]) < 0.05 * s_true
