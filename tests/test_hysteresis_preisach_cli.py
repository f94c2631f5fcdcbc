"""`stageid simulate` on a Preisach model file."""

import json

import numpy as np

from stageid.cli.main import main
from stageid.hysteresis.models.preisach import PreisachModel
from stageid.models.serialization import dumps


def test_simulate_runs_a_preisach_file(tmp_path):
    rng = np.random.default_rng(0)
    m = PreisachModel((-1.0, 1.0), rng.random(15), output_offset=0.2)
    (tmp_path / "m.json").write_text(dumps(m.to_dict()))
    u = np.sin(np.linspace(0, 12, 200)) * np.linspace(1, 0.2, 200)
    (tmp_path / "u.csv").write_text("V\n" + "\n".join(repr(float(v)) for v in u) + "\n")
    code = main(["simulate", str(tmp_path / "m.json"), str(tmp_path / "u.csv"), "-o", str(tmp_path / "y.csv")])
    assert code in (0, None)
    y = np.loadtxt(tmp_path / "y.csv", delimiter=",", skiprows=1, ndmin=2)[:, -1]
    np.testing.assert_allclose(y, m(u), atol=1e-12)
    assert json.loads((tmp_path / "m.json").read_text())["kind"] == "preisach"


def _record(tmp_path, name="decaying-triangle"):
    from stageid.plants.piezo_actuator import EXPERIMENTS

    e = EXPERIMENTS[name](seed=0)
    path = tmp_path / f"{name}.csv"
    np.savetxt(path, np.c_[np.arange(len(e.u)) * e.dt, e.u, e.y], delimiter=",", header="t,V,y", comments="")
    return path, e


def test_identify_preisach_writes_a_model_that_simulate_reproduces(tmp_path):
    from stageid.hysteresis import PreisachIdentifier
    from stageid.models import load_model

    path, e = _record(tmp_path)
    out = tmp_path / "p.json"
    args = ["identify", "hysteresis", str(path), "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, "--levels", "12", "--quiet", "-o", str(out)]) == 0
    model = load_model(str(out))
    direct = PreisachIdentifier(n_levels=12).fit(e).model
    np.testing.assert_array_equal(model.weights, direct.weights)  # the CLI is the estimator


def test_a_grid_finer_than_the_records_is_filled_with_one_line(tmp_path, capsys):
    path, _ = _record(tmp_path)
    out = tmp_path / "p.json"
    args = ["identify", "hysteresis", str(path), "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, "--levels", "30", "-o", str(out)]) == 0
    text = capsys.readouterr().out.strip().splitlines()
    filled = [line for line in text if "the smoothness prior filled" in line]
    assert len(filled) == 1 and "cells the records leave undetermined" in filled[0]
    assert out.exists()


def test_a_constant_input_is_one_line_exit_2_no_file(tmp_path, capsys):
    path = tmp_path / "c.csv"
    y = np.sin(np.arange(300) / 9.0)
    np.savetxt(path, np.c_[np.arange(300) * 1e-3, np.full(300, 2.5), y], delimiter=",", header="t,V,y", comments="")
    out = tmp_path / "p.json"
    args = ["identify", "hysteresis", str(path), "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, "--levels", "8", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "constant input" in err and "\n" not in err
    assert not out.exists()
