"""`stageid report` and the identify verbs' `--report DIR`."""

import json

import numpy as np

from stageid.cli.main import main
from stageid.data.io import write_csv
from stageid.models import StateSpaceModel, save_model


def _record(tmp_path):
    rng = np.random.default_rng(3)
    g = StateSpaceModel(
        [[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=0.01, inputs=("u",), outputs=("y",)
    )
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
    rc = main(
        [
            "identify",
            "statespace",
            str(tmp_path / "rec.csv"),
            "--inputs",
            "u",
            "--outputs",
            "y",
            "--order",
            "2",
            "--horizon",
            "10",
            "-o",
            str(tmp_path / "m.json"),
            "--report",
            str(tmp_path / "rep"),
        ]
    )
    assert rc == 0 and (tmp_path / "m.json").exists()
    html = (tmp_path / "rep" / "index.html").read_text()
    assert "Hankel-MAP diagnostics" in html
    assert html.count("<img src='data:image/png;base64,") >= 4  # Bode, pole-zero, simulation, posterior bands


def test_identify_hysteresis_report(tmp_path):
    from stageid.data.io import write_csv as write
    from stageid.plants.piezo_actuator import EXPERIMENTS

    write(tmp_path / "ident.csv", EXPERIMENTS["decaying-triangle"](seed=0))
    rc = main(
        [
            "identify",
            "hysteresis",
            str(tmp_path / "ident.csv"),
            "--input",
            "V",
            "--output",
            "y",
            "--model",
            "pi",
            "--operators",
            "10",
            "-o",
            str(tmp_path / "h.json"),
            "--report",
            str(tmp_path / "rep"),
            "--quiet",
        ]
    )
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
    K = StateSpaceModel(
        np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], dt=0.001, inputs=("e",), outputs=("u",)
    )
    save_model(K, tmp_path / "K.json")
    r = rng.standard_normal(4000)
    r[:100] = 0.0  # the loop starts at rest
    yu = feedback(G, K).simulate(r[:, None])
    write_csv(
        tmp_path / "exp.csv", {"r_y": r, "y": yu[:, 0] + 1e-5 * rng.standard_normal(4000), "u": yu[:, 1]}, dt=0.001
    )
    rc = main(
        [
            "identify",
            "closed-loop",
            str(tmp_path / "exp.csv"),
            "--references",
            "r_y",
            "--outputs",
            "y",
            "--controller",
            str(tmp_path / "K.json"),
            "--structure",
            "full",
            "--band",
            "1:100",
            "-o",
            str(tmp_path / "G.json"),
            "--report",
            str(tmp_path / "rep"),
        ]
    )
    assert rc == 0
    html = (tmp_path / "rep" / "index.html").read_text()
    # plant Bode, its +-2 std bands, pole-zero, closed loop vs ETFE, re-closed loop
    assert html.count("<img src='data:image/png;base64,") == 5
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert metrics["uncertainty/relative_std_median_percent/y_u"] > 0
    fits = [v for k, v in metrics.items() if k.startswith("reclosed_fit_percent/") and k.endswith("/y")]
    assert len(fits) == 1 and fits[0] > 99.0  # the identified plant re-closed with K reproduces y
    s_true = np.log(1.02) / 0.001
    assert min(abs(p - s_true) for p in metrics["unstable_poles_rad_s"]) < 0.05 * s_true


# ----------------------------------------------------------------- regressions of the bug hunt
def test_report_with_a_constant_output_channel_completes(tmp_path, capsys):
    g = StateSpaceModel([[0.9]], [[1.0]], [[0.5], [0.2]], [[0.0], [0.0]], dt=0.01, inputs=("u",), outputs=("y", "z"))
    save_model(g, tmp_path / "g.json")
    u = np.random.default_rng(5).standard_normal(500)
    y = g.simulate(u[:, None])
    write_csv(tmp_path / "flat.csv", {"u": u, "y": y[:, 0], "z": np.zeros(500)}, dt=0.01)  # sensor z did not move
    rc = main(["report", str(tmp_path / "g.json"), str(tmp_path / "flat.csv"), "--out", str(tmp_path / "rep")])
    assert rc == 0, capsys.readouterr().err
    text = (tmp_path / "rep" / "metrics.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    metrics = json.loads(text)
    assert metrics["fit_percent/flat.csv/z"] is None and metrics["fit_percent/flat.csv/y"] > 99.0
    assert "<td>n/a</td>" in (tmp_path / "rep" / "index.html").read_text()


def test_hysteresis_report_with_a_constant_output_completes(tmp_path, capsys):
    from stageid.hysteresis import PIModel

    save_model(PIModel(r=[0.0, 20.0, 40.0], weights=[0.01, 0.005, 0.002]), tmp_path / "pi.json")
    v = 50.0 * (1 - np.cos(np.linspace(0, 4 * np.pi, 400)))
    write_csv(tmp_path / "yflat.csv", {"V": v, "y": np.full(400, 1.5)}, dt=0.001)
    rc = main(
        [
            "report",
            str(tmp_path / "pi.json"),
            str(tmp_path / "yflat.csv"),
            "--inputs",
            "V",
            "--outputs",
            "y",
            "--out",
            str(tmp_path / "rep"),
        ]
    )
    assert rc == 0, capsys.readouterr().err
    assert json.loads((tmp_path / "rep" / "metrics.json").read_text()) == {
        "max_error_percent_range/yflat.csv": None,
        "units": {"max_error_percent_range/yflat.csv": "% of the output's range"},
    }


def test_a_failing_report_leaves_no_folder(tmp_path, monkeypatch, capsys):
    import stageid.report.html as html_module

    g = _record(tmp_path)
    save_model(g, tmp_path / "g.json")

    def broken_dumps(*args, **kwargs):
        raise ValueError("metrics cannot be serialised")

    monkeypatch.setattr(html_module.json, "dumps", broken_dumps)  # fails after the HTML was rendered
    rc = main(["report", str(tmp_path / "g.json"), str(tmp_path / "rec.csv"), "--out", str(tmp_path / "rep")])
    assert rc == 3 and "metrics cannot be serialised" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.json", "rec.csv"]  # no rep/, no index.html, no temp folder


def test_report_into_a_missing_directory_is_refused_before_work(tmp_path, capsys):
    g = _record(tmp_path)
    save_model(g, tmp_path / "g.json")
    rc = main(["report", str(tmp_path / "g.json"), "--out", str(tmp_path / "nodir" / "rep")])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "directory" in err and "nodir' does not exist" in err
    assert not (tmp_path / "nodir").exists()
