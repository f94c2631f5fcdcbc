"""The edge-transient hint (``try `start=...``` in the library, ``try --start ...`` on the command line)
for LTI models: ``identify statespace`` and ``validate``, in the wording ``identify hysteresis`` uses."""

from __future__ import annotations

import json

import numpy as np

from conftest import run_main
from stageid.data import write_csv
from stageid.validation.edges import lti_edge_lines

DT = 1e-3
N = 2000
POLE = 0.9


def _record(path, seed=0, settle=0.0, start_state=0.0, glitch=0.0):
    """First-order stage y(k) = 0.9 y(k-1) + 0.1 u(k-1), white input, small sensor noise.

    ``settle``: a sensor settling over the first 60 samples (not the stage's dynamics);
    ``start_state``: the stage already moving when the capture starts; ``glitch``: the last sample off.
    """
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    y = np.zeros(N)
    y[0] = start_state
    for k in range(1, N):
        y[k] = POLE * y[k - 1] + (1 - POLE) * u[k - 1]
    y += 0.002 * rng.standard_normal(N)
    y[:60] += settle * np.exp(-np.arange(60) / 15.0)
    y[-1] += glitch
    write_csv(path, {"t": DT * np.arange(N), "u": u, "y": y})
    return path


def _model(path):
    model = {
        "format": "stageid.lti/1",
        "kind": "statespace",
        "dt": DT,
        "A": [[POLE]],
        "B": [[1 - POLE]],
        "C": [[1.0]],
        "D": [[0.0]],
        "inputs": ["u"],
        "outputs": ["y"],
    }
    path.write_text(json.dumps(model))
    return path


def test_statespace_points_at_a_start_transient_and_start_removes_it(tmp_path):
    rec = _record(tmp_path / "rec.csv", settle=0.8)
    args = ["identify", "statespace", rec, "--inputs", "u", "--outputs", "y", "--order", "1"]
    code, out, err = run_main(*args, "-o", tmp_path / "m.json")
    assert code == 0, err
    (line,) = [s for s in out.splitlines() if "transient" in s]
    assert line.startswith("rec.csv  y: max error in the first 60 samples") and line.endswith(
        "a start-up transient; try --start 0.06"
    )
    code, out, err = run_main(*args, "--start", "0.06", "-o", tmp_path / "trimmed.json")
    assert code == 0 and "transient" not in out + err


def test_statespace_points_at_an_end_glitch(tmp_path):
    rec = _record(tmp_path / "rec.csv", seed=1, glitch=0.6)
    code, out, err = run_main(
        "identify", "statespace", rec, "--inputs", "u", "--outputs", "y", "--order", "1", "-o", tmp_path / "m.json"
    )
    assert code == 0, err
    (line,) = [s for s in out.splitlines() if "transient" in s]
    assert "max error in the last sample" in line and line.endswith(f"try --stop {(N - 2) * DT:.6g}")


def test_validate_lti_hint_blames_the_record_not_the_start_from_rest(tmp_path):
    model = _model(tmp_path / "m.json")
    # the stage was moving when the capture started: from rest the first samples miss by the
    # stage's own decay, which no trim fixes; from the estimated state nothing is left
    moving = _record(tmp_path / "moving.csv", seed=2, start_state=1.5)
    for initial in ("model", "estimate"):
        code, out, err = run_main("validate", model, moving, "--initial", initial)
        assert code == 0 and "fit" in out and "transient" not in out + err, out + err
    settling = _record(tmp_path / "settling.csv", seed=3, settle=0.8)
    code, out, err = run_main("validate", model, settling)
    assert code == 0, err
    assert "settling.csv  y: max error in the first 60 samples" in out and "try --start 0.06" in out


def test_lti_edge_lines_in_the_library(tmp_path):
    from stageid.data import read_table
    from stageid.models import load_model

    model = load_model(_model(tmp_path / "m.json"))
    exp = read_table(_record(tmp_path / "r.csv", seed=4, settle=0.8)).experiment(["u"], ["y"], name="r")
    clean = read_table(_record(tmp_path / "c.csv", seed=4)).experiment(["u"], ["y"], name="c")
    (line,) = lti_edge_lines(model, [exp, clean])
    assert (
        line.startswith("r  y: ") and "try `start=0.06`" in line
    )  # the library names the parameter; the CLI prints --start
    assert lti_edge_lines(model, [clean]) == []


def test_an_unstable_model_gets_no_hint(tmp_path):
    # its response overflows within the record: the hint must not turn a fit into an error
    from stageid.data import read_table
    from stageid.models import StateSpaceModel

    unstable = StateSpaceModel([[1.5]], [[0.1]], [[1.0]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",))
    exp = read_table(_record(tmp_path / "r.csv", seed=5, settle=0.8)).experiment(["u"], ["y"], name="r")
    assert lti_edge_lines(unstable, [exp]) == []
