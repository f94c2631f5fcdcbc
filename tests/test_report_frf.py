"""`stageid report --frf`: a measured frequency response beside the model."""

import json

import numpy as np

from conftest import assert_one_line_error, run_main, snapshot
from stageid.hysteresis import PIModel
from stageid.models import StateSpaceModel, save_model

DT = 0.01


def _model(gain=1.0):
    A = [[0.9, 0.2], [-0.2, 0.9]]
    return StateSpaceModel(
        A, [[1.0, 0.0], [0.0, 1.0]], [[gain * 0.5, 0.1]], [[0.0, 0.0]], dt=DT, inputs=("a", "b"), outputs=("y",)
    )


def test_the_model_against_its_own_response_and_a_scaled_one(tmp_path):
    save_model(_model(), tmp_path / "m.json")
    save_model(_model(gain=1.1), tmp_path / "m11.json")
    rc, _, err = run_main(
        "freqresp", tmp_path / "m.json", "--fmin", "0.1", "--fmax", "40", "--n", "200", "-o", tmp_path / "fr.csv"
    )
    assert rc == 0, err
    rc, _, err = run_main("report", tmp_path / "m.json", "--frf", tmp_path / "fr.csv", "--out", tmp_path / "rep")
    assert rc == 0, err
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert metrics["frf/column_error_percent/a"] < 1e-9 and metrics["frf/column_error_percent/b"] < 1e-9
    assert "Measured frequency response" in (tmp_path / "rep" / "index.html").read_text()
    # a model whose first state's output weight is 10 % larger: the error is that of the
    # responses, computed here independently of the report
    rc, _, err = run_main("report", tmp_path / "m11.json", "--frf", tmp_path / "fr.csv", "--out", tmp_path / "rep2")
    assert rc == 0, err
    metrics = json.loads((tmp_path / "rep2" / "metrics.json").read_text())
    f = np.geomspace(0.1, 40, 200)
    G, G11 = _model().frequency_response(f), _model(1.1).frequency_response(f)
    expected = np.max(np.abs(G11 - G), axis=(0, 1)) / np.max(np.abs(G), axis=(0, 1))
    np.testing.assert_allclose(
        [metrics["frf/column_error_percent/a"], metrics["frf/column_error_percent/b"]], 100 * expected, rtol=1e-9
    )


def test_channels_come_by_the_given_names(tmp_path):
    g = _model()
    save_model(g, tmp_path / "m.json")
    renamed = StateSpaceModel(g.A, g.B, g.C, g.D, dt=DT, inputs=("u1", "u2"), outputs=("z",))
    save_model(renamed, tmp_path / "r.json")
    rc, _, err = run_main(
        "freqresp", tmp_path / "r.json", "--fmin", "1", "--fmax", "40", "--n", "50", "-o", tmp_path / "fr.csv"
    )
    assert rc == 0, err
    rc, _, err = run_main(
        "report",
        tmp_path / "m.json",
        "--frf",
        tmp_path / "fr.csv",
        "--inputs",
        "u1,u2",
        "--outputs",
        "z",
        "--out",
        tmp_path / "rep",
    )
    assert rc == 0, err
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert metrics["frf/column_error_percent/a"] < 1e-9


def test_bad_frf_input_is_one_line_and_writes_nothing(tmp_path):
    save_model(_model(), tmp_path / "m.json")
    save_model(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), tmp_path / "h.json")
    rc, _, err = run_main(
        "freqresp", tmp_path / "m.json", "--fmin", "1", "--fmax", "40", "--n", "50", "-o", tmp_path / "fr.csv"
    )
    assert rc == 0, err
    before = snapshot(tmp_path)
    rc, _, err = run_main(
        "report", tmp_path / "m.json", "--frf", tmp_path / "fr.csv", "--inputs", "a,c", "--out", tmp_path / "rep"
    )
    assert_one_line_error(rc, err, "has no channel 'c'")
    rc, _, err = run_main("report", tmp_path / "h.json", "--frf", tmp_path / "fr.csv", "--out", tmp_path / "rep")
    assert_one_line_error(rc, err, "--frf needs a linear model")
    (tmp_path / "bad.csv").write_text("f_hz,re_y_a\n1,2\n")
    rc, _, err = run_main("report", tmp_path / "m.json", "--frf", tmp_path / "bad.csv", "--out", tmp_path / "rep")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    (tmp_path / "bad.csv").unlink()
    assert snapshot(tmp_path) == before
