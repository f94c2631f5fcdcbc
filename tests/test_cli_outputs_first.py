"""Every verb refuses a bad output in one line *before* any work, and writes through the shared helpers.

A bad ``-o`` (missing directory, wrong extension, ``-``) or ``--report`` folder must be refused
before the model is loaded, the records are read or anything is fitted: the tests replace the
loaders and the fitting methods by functions that record the call and raise, so a check done
after the work fails them (exit code 3, "internal error", a recorded call).
"""

import json

import numpy as np
import pytest

from conftest import assert_one_line_error, run_main
from stageid._errors import ModelFormatError
from stageid.data.io import read_table, write_csv
from stageid.hysteresis import PIModel
from stageid.models import StateSpaceModel, save_model
from stageid.models.serialization import loads

DT = 0.01


@pytest.fixture
def inputs(tmp_path, monkeypatch):
    """Valid input files in ``in/`` (a verb with a good -o would run on them); cwd is tmp_path."""
    d = tmp_path / "in"
    d.mkdir()
    rng = np.random.default_rng(7)
    # open loop: a stable discrete SISO model and a record of it
    g = StateSpaceModel(
        [[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",)
    )
    save_model(g, d / "g.json")
    u = rng.standard_normal(600)
    write_csv(d / "rec.csv", {"u": u, "y": g.simulate(u[:, None])[:, 0]}, dt=DT)
    # hysteresis: a classical PI model, a triangle drive and its output, a reference to track
    h = PIModel(r=[0.0, 20.0, 40.0], weights=[0.01, 0.005, 0.002])
    save_model(h, d / "h.json")
    v = 50.0 * (1 - np.cos(np.linspace(0, 6 * np.pi, 600)))
    write_csv(d / "hyst.csv", {"V": v, "y": h.simulate(v)[:, 0]}, dt=DT)
    write_csv(d / "ref.csv", {"yref": 0.3 * (1 - np.cos(np.linspace(0, 2 * np.pi, 200)))}, dt=DT)
    # closed loop: an unstable first-order plant under a proportional controller
    from stageid.models import feedback

    G = StateSpaceModel([[1.02]], [[0.05]], [[1.0]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",))
    K = StateSpaceModel(
        np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], dt=DT, inputs=("e",), outputs=("u",)
    )
    save_model(K, d / "K.json")
    r = rng.standard_normal(2000)
    r[:100] = 0.0
    yu = feedback(G, K).simulate(r[:, None])
    write_csv(d / "cl.csv", {"r_y": r, "y": yu[:, 0], "u": yu[:, 1]}, dt=DT)
    monkeypatch.chdir(tmp_path)
    return d


@pytest.fixture
def no_work(monkeypatch):
    """Make every loader and fitting step record its call and raise; returns the list of calls."""
    import stageid.closedloop
    import stageid.data.io
    import stageid.hysteresis
    import stageid.models
    import stageid.subspace.estimator

    calls = []

    def forbid(name):
        def work(*args, **kwargs):
            calls.append(name)
            raise AssertionError(f"{name} ran before the output was checked")

        return work

    monkeypatch.setattr(stageid.models, "load_model", forbid("load_model"))
    monkeypatch.setattr(stageid.data.io, "read_table", forbid("read_table"))
    monkeypatch.setattr(stageid.subspace.estimator.HankelMAP, "fit", forbid("HankelMAP.fit"))
    monkeypatch.setattr(stageid.hysteresis.PIIdentifier, "fit", forbid("PIIdentifier.fit"))
    monkeypatch.setattr(stageid.closedloop.ClosedLoopIdentification, "fit", forbid("ClosedLoopIdentification.fit"))
    monkeypatch.setattr(stageid.hysteresis.Compensator, "run", forbid("Compensator.run"))
    return calls


# the command line of each verb without its output option, and the name of that option
VERBS = {
    "simulate": (["simulate", "in/g.json", "in/rec.csv"], "-o", "table"),
    "simulate-hysteresis": (["simulate", "in/h.json", "in/hyst.csv"], "-o", "table"),
    "compensate": (["compensate", "in/h.json", "in/ref.csv", "--column", "yref"], "-o", "table"),
    "identify-statespace": (
        ["identify", "statespace", "in/rec.csv", "--inputs", "u", "--outputs", "y", "--order", "2", "--horizon", "10"],
        "-o",
        "model",
    ),
    "identify-hysteresis": (
        [
            "identify",
            "hysteresis",
            "in/hyst.csv",
            "--input",
            "V",
            "--output",
            "y",
            "--model",
            "pi",
            "--operators",
            "3",
            "--quiet",
        ],
        "-o",
        "model",
    ),
    "identify-closedloop": (
        [
            "identify",
            "closed-loop",
            "in/cl.csv",
            "--references",
            "r_y",
            "--outputs",
            "y",
            "--controller",
            "in/K.json",
            "--structure",
            "full",
            "--band",
            "1:40",
        ],
        "-o",
        "model",
    ),
}
GOOD = {"table": "out.csv", "model": "out.json"}
BAD = {
    "table": [
        ("nodir/out.csv", "cannot write 'nodir/out.csv': directory 'nodir' does not exist."),
        ("out.json", "output 'out.json' has extension '.json'; expected .csv or .npz for a table."),
        ("out.txt", "expected .csv or .npz for a table"),
        ("-", "-o '-' (standard output) is not supported"),
    ],
    "model": [
        ("nodir/out.json", "cannot write 'nodir/out.json': directory 'nodir' does not exist."),
        ("out.csv", "output 'out.csv' has extension '.csv'; expected .json for a model."),
        ("out", "output 'out' has no extension; expected .json for a model."),
        ("-", "-o '-' (standard output) is not supported"),
    ],
}
CASES = [(verb, bad, fragment) for verb, (_, _, kind) in VERBS.items() for bad, fragment in BAD[kind]]


@pytest.mark.parametrize("verb, bad, fragment", CASES, ids=[f"{v}:{b}" for v, b, _ in CASES])
def test_a_bad_output_is_refused_in_one_line_before_any_work(tmp_path, inputs, no_work, verb, bad, fragment):
    args, flag, _ = VERBS[verb]
    rc, out, err = run_main(*args, flag, bad)
    assert_one_line_error(rc, err, fragment)
    assert no_work == []  # neither the model, nor the records were read, nothing was fitted
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]  # no output, no '-' file, no temporary file


REPORT_VERBS = ["identify-statespace", "identify-hysteresis", "identify-closedloop"]


@pytest.mark.parametrize("verb", REPORT_VERBS)
def test_a_bad_report_folder_is_refused_before_any_work(tmp_path, inputs, no_work, verb):
    args, flag, kind = VERBS[verb]
    rc, _, err = run_main(*args, flag, GOOD[kind], "--report", "nodir/rep")
    assert_one_line_error(rc, err, "directory 'nodir' does not exist")
    (tmp_path / "afile").write_text("x")
    rc, _, err = run_main(*args, flag, GOOD[kind], "--report", "afile")
    assert_one_line_error(rc, err, "'afile' is a file")  # click's Path(file_okay=False) says it first
    assert no_work == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "in"]  # no model file written either


@pytest.mark.parametrize("verb", list(VERBS))
def test_a_good_output_is_written_by_extension(tmp_path, inputs, verb):
    # the same command lines do work with a good -o (so the refusals above are about the output)
    args, flag, kind = VERBS[verb]
    target = "out.npz" if kind == "table" else "out.json"
    rc, _, err = run_main(*args, flag, target)
    assert rc == 0, err
    if kind == "table":
        assert (tmp_path / target).read_bytes()[:2] == b"PK"  # an NPZ archive, not CSV text in a .npz file
        table = read_table(tmp_path / target)
        assert table.names == (("V",) if verb == "compensate" else ("y",)) and table.dt == pytest.approx(DT)
    else:
        assert json.loads((tmp_path / target).read_text())["format"] in ("stageid.lti/1", "stageid.hysteresis/1")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", target]  # no temporary file left


def test_simulate_npz_equals_csv(tmp_path, inputs):
    assert run_main("simulate", "in/g.json", "in/rec.csv", "-o", "a.csv")[0] == 0
    assert run_main("simulate", "in/g.json", "in/rec.csv", "-o", "a.npz")[0] == 0
    a, b = read_table(tmp_path / "a.csv"), read_table(tmp_path / "a.npz")
    np.testing.assert_array_equal(a.column("y"), b.column("y"))  # both formats are exact (shortest repr / binary)


def test_a_failing_closed_loop_report_leaves_no_folder(tmp_path, inputs, monkeypatch):
    # the closed-loop report goes through write_report_folder: all or nothing
    import stageid.report.html as html_module

    def broken_metrics_json(*args, **kwargs):
        raise ValueError("metrics cannot be serialised")

    # fails after the HTML was rendered (json.dumps itself is not patched: the model file uses it)
    monkeypatch.setattr(html_module, "metrics_json", broken_metrics_json)
    args, flag, _ = VERBS["identify-closedloop"]
    rc, _, err = run_main(*args, flag, "G.json", "--report", "rep")
    assert rc == 3 and "metrics cannot be serialised" in err
    # outputs are committed together: no G.json, no rep/, no temporary folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


# ------------------------------------------------------------------ stageid report: renaming lists
@pytest.fixture
def two_input_model(tmp_path, monkeypatch):
    g = StateSpaceModel([[0.9]], [[1.0, 0.5]], [[0.5]], [[0.0, 0.0]], dt=DT, inputs=("a", "b"), outputs=("y",))
    save_model(g, tmp_path / "g.json")
    rng = np.random.default_rng(3)
    write_csv(tmp_path / "r.csv", {name: rng.standard_normal(300) for name in ("p", "q", "s", "y", "z")}, dt=DT)
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize(
    "names, fragment",
    [
        (["--inputs", "p,q,s"], "--inputs: expected 2 names for the model's inputs (a,b); got 3 (p,q,s)."),
        (["--inputs", "p"], "--inputs: expected 2 names for the model's inputs (a,b); got 1 (p)."),
        (
            ["--inputs", "p,q", "--outputs", "y,z"],
            "--outputs: expected 1 name for the model's outputs (y); got 2 (y,z).",
        ),
    ],
)
def test_report_renaming_lists_must_match_the_model(tmp_path, two_input_model, names, fragment):
    rc, _, err = run_main("report", "g.json", "r.csv", *names, "--out", "rep")
    assert_one_line_error(rc, err, fragment)
    assert not (tmp_path / "rep").exists()


def test_report_renaming_lists_of_the_right_length_work(tmp_path, two_input_model):
    rc, _, err = run_main("report", "g.json", "r.csv", "--inputs", "p,q", "--outputs", "z", "--out", "rep")
    assert rc == 0, err
    assert "fit_percent/r.csv/y" in json.loads(
        (tmp_path / "rep" / "metrics.json").read_text()
    )  # z shown as the model's y


# ------------------------------------------------------------------ model files without `format`
def test_a_model_without_format_names_the_accepted_formats():
    with pytest.raises(ModelFormatError) as info:
        loads('{"kind": "statespace", "dt": 0.1, "A": [[0.5]]}')
    assert str(info.value) == (
        "`format` is missing; expected one of stageid.hysteresis/1, stageid.lti/1; "
        "got an object without it (keys: A, dt, kind)."
    )
    with pytest.raises(
        ModelFormatError, match=r"expected one of stageid.hysteresis/1, stageid.lti/1; got an empty object\.$"
    ):
        loads("{}")
    with pytest.raises(ModelFormatError, match=r"stageid.lti/1; got `format`: null\.$"):
        loads('{"format": null}')


def test_a_model_file_without_format_is_one_line_in_the_cli(tmp_path, inputs):
    (tmp_path / "in" / "bare.json").write_text('{"kind": "statespace"}\n')
    rc, _, err = run_main("simulate", "in/bare.json", "in/rec.csv", "-o", "y.csv")
    assert_one_line_error(
        rc,
        err,
        "bare.json: `format` is missing; expected one of stageid.hysteresis/1, stageid.lti/1; "
        "got an object without it (keys: kind).",
    )
    assert not (tmp_path / "y.csv").exists()
