"""`stageid simulate` on a Preisach model file."""

import json

import numpy as np

from stageid.cli.main import main
from stageid.hysteresis.preisach import PreisachModel
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
