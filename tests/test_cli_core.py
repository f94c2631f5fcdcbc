"""The `stageid` command line: simulate, freqresp, signal, plants and its error contract."""

import json

import numpy as np
import pytest

import conftest
from conftest import assert_one_line_error
from stageid.cli.main import main
from stageid.data.io import read_table, write_csv
from stageid.models import StateSpaceModel, TransferMatrix, save_model


def run_main(*args):
    """Run `stageid` in this process with warnings as errors: a RuntimeWarning leaking before
    the error fails the contract (test_failure_contract.py holds it for the real process)."""
    return conftest.run_main(*args, warnings_as_errors=True)


@pytest.fixture
def discrete_model(tmp_path):
    rng = np.random.default_rng(11)
    A = rng.standard_normal((4, 4))
    A *= 0.95 / np.max(np.abs(np.linalg.eigvals(A)))
    g = StateSpaceModel(
        A,
        rng.standard_normal((4, 2)),
        rng.standard_normal((3, 4)),
        rng.standard_normal((3, 2)),
        dt=0.002,
        inputs=("Z", "Rx"),
        outputs=("z", "rx", "ry"),
    )
    path = tmp_path / "g.json"
    save_model(g, path)
    return g, path


def test_simulate_equals_the_recursion(tmp_path, discrete_model):
    g, model_path = discrete_model
    rng = np.random.default_rng(12)
    u = rng.standard_normal((3000, 2))
    write_csv(tmp_path / "u.csv", {"Rx": u[:, 1], "other": u[:, 0] * 0, "Z": u[:, 0]}, dt=0.002)
    assert main(["simulate", str(model_path), str(tmp_path / "u.csv"), "-o", str(tmp_path / "y.csv")]) == 0
    out = read_table(tmp_path / "y.csv")
    assert out.names == ("z", "rx", "ry") and np.isclose(out.dt, 0.002)
    x = np.zeros(4)
    y_ref = np.empty((3000, 3))
    for k in range(3000):
        y_ref[k] = g.C @ x + g.D @ u[k]
        x = g.A @ x + g.B @ u[k]
    np.testing.assert_allclose(out.values, y_ref, rtol=0, atol=1e-9)


def test_simulate_npz_without_time_uses_model_dt(tmp_path, discrete_model):
    g, model_path = discrete_model
    u = np.random.default_rng(13).standard_normal((50, 2))
    np.savez(tmp_path / "u.npz", Z=u[:, 0], Rx=u[:, 1])
    assert main(["simulate", str(model_path), str(tmp_path / "u.npz"), "-o", str(tmp_path / "y.csv")]) == 0
    np.testing.assert_allclose(read_table(tmp_path / "y.csv").values, g.simulate(u), atol=1e-12)


@pytest.mark.parametrize("kind", ["statespace", "transfer"])
def test_freqresp_continuous_equals_formula(tmp_path, kind):
    rng = np.random.default_rng(14)
    if kind == "statespace":
        A = rng.standard_normal((5, 5)) - 3 * np.eye(5)
        model = StateSpaceModel(
            A,
            rng.standard_normal((5, 2)),
            rng.standard_normal((2, 5)),
            rng.standard_normal((2, 2)),
            inputs=("a", "b"),
            outputs=("x", "y"),
        )

        def truth(s):
            return model.C @ np.linalg.solve(s * np.eye(5) - A, model.B) + model.D
    else:
        num = [[[1.0, 2.0], [3.0]], [[0.5, 0.0, 1.0], [2.0, 1.0]]]
        den = [[[1.0, 3.0, 2.0], [1.0, 1.0]], [[1.0, 2.0, 5.0], [1.0, 4.0, 4.0]]]
        model = TransferMatrix(num, den, None, ("a", "b"), ("x", "y"))

        def truth(s):
            return np.array([[np.polyval(num[i][j], s) / np.polyval(den[i][j], s) for j in range(2)] for i in range(2)])

    save_model(model, tmp_path / "m.json")
    assert (
        main(
            [
                "freqresp",
                str(tmp_path / "m.json"),
                "--fmin",
                "0.1",
                "--fmax",
                "100",
                "--n",
                "25",
                "-o",
                str(tmp_path / "fr.csv"),
            ]
        )
        == 0
    )
    header = (tmp_path / "fr.csv").read_text().splitlines()[0].split(",")
    assert header == ["f_hz", "re_x_a", "im_x_a", "re_x_b", "im_x_b", "re_y_a", "im_y_a", "re_y_b", "im_y_b"]
    data = np.loadtxt(tmp_path / "fr.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 0], np.geomspace(0.1, 100, 25), rtol=1e-12)
    for row in data:
        expected = truth(2j * np.pi * row[0])
        got = np.array([[row[1] + 1j * row[2], row[3] + 1j * row[4]], [row[5] + 1j * row[6], row[7] + 1j * row[8]]])
        np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-9)


def test_nan_in_csv_is_one_line_error_and_no_output(tmp_path, discrete_model):
    _, model_path = discrete_model
    lines = ["t,Z,Rx"] + [f"{k * 0.002},{k},{-k}" for k in range(20)]
    lines[8] = "0.014,nan,1"  # data row 7 (header is lines[0])
    (tmp_path / "u.csv").write_text("\n".join(lines) + "\n")
    rc, out, err = run_main("simulate", model_path, tmp_path / "u.csv", "-o", tmp_path / "y.csv")
    assert_one_line_error(rc, err)
    assert rc == 2
    assert "'Z'" in err and "NaN" in err and "row 7" in err
    assert not (tmp_path / "y.csv").exists()


def test_wrong_b_rows_is_one_line_error_and_no_output(tmp_path):
    d = {
        "format": "stageid.lti/1",
        "kind": "statespace",
        "dt": None,
        "A": np.eye(3).tolist(),
        "B": np.ones((2, 1)).tolist(),
        "C": np.ones((1, 3)).tolist(),
        "D": [[0.0]],
        "inputs": ["u"],
        "outputs": ["y"],
    }
    (tmp_path / "bad.json").write_text(json.dumps(d))
    rc, out, err = run_main("freqresp", tmp_path / "bad.json", "--fmin", "1", "--fmax", "10", "-o", tmp_path / "fr.csv")
    assert_one_line_error(rc, err)
    assert rc == 2 and "`B` must have shape (3, 1); got (2, 1)" in err
    assert not (tmp_path / "fr.csv").exists()
    write_csv(tmp_path / "u.csv", {"u": np.ones(10)}, dt=0.1)
    rc, out, err = run_main("simulate", tmp_path / "bad.json", tmp_path / "u.csv", "-o", tmp_path / "y.csv")
    assert_one_line_error(rc, err)
    assert not (tmp_path / "y.csv").exists()


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["simulate", "{m}", "{missing}", "-o", "{out}"], "does not exist"),
        (["freqresp", "{m}", "--fmin", "-1", "--fmax", "10", "-o", "{out}"], "--fmin"),
        (["freqresp", "{m}", "--fmin", "1", "--fmax", "1000", "-o", "{out}"], "Nyquist"),
        (
            [
                "signal",
                "chirp",
                "--f0",
                "1",
                "--f1",
                "10",
                "--duration",
                "1",
                "--dt",
                "0.01",
                "--limits",
                "0:0.5",
                "-o",
                "{out}",
            ],
            "limits",
        ),
        (["simulate", "{m}", "{u_wrong}", "-o", "{out}"], "the model's input(s) Z"),
        (["nonsense"], "No such command"),
    ],
)
def test_bad_input_contract(tmp_path, discrete_model, args, fragment):
    _, model_path = discrete_model
    write_csv(tmp_path / "u_wrong.csv", {"a": np.ones(5), "b": np.ones(5)}, dt=0.002)
    subst = {
        "m": model_path,
        "missing": tmp_path / "missing.csv",
        "out": tmp_path / "out.csv",
        "u_wrong": tmp_path / "u_wrong.csv",
    }
    rc, out, err = run_main(*[a.format(**subst) for a in args])
    assert_one_line_error(rc, err)
    assert rc == 2
    assert fragment in err
    assert not (tmp_path / "out.csv").exists()


def test_signal_writes_chirp_of_the_paper(tmp_path):
    out = tmp_path / "z.csv"
    assert (
        main(
            [
                "signal",
                "chirp",
                "--f0",
                "1",
                "--f1",
                "100",
                "--duration",
                "10",
                "--dt",
                "0.002",
                "--amplitude",
                "20",
                "--offset",
                "20",
                "--name",
                "Z",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    table = read_table(out)
    z = table.column("Z")
    assert table.dt == pytest.approx(0.002) and z.size == 5000
    assert z.min() >= 0.0 and z.max() <= 40.0 and z.max() > 39.9


def test_help_shows_examples():
    rc, out, err = run_main("--help")
    assert rc == 0 and "Examples:" in out and "identify" in out


def test_logger_time_jitter_is_accepted_but_a_missing_sample_is_not(tmp_path, discrete_model):
    # single-precision time stamps scatter by ~1e-4 of dt (real dSPACE/EMPS records); a dropped sample is a 100 % step
    g, model_path = discrete_model
    n = 200
    t = (np.arange(n) * 0.002).astype(np.float32).astype(float) + 0.002 * 1e-4 * np.sin(np.arange(n))
    u = np.random.default_rng(15).standard_normal((n, 2))
    rows = ["t,Z,Rx"] + [f"{float(t[k])!r},{float(u[k, 0])!r},{float(u[k, 1])!r}" for k in range(n)]
    (tmp_path / "jitter.csv").write_text("\n".join(rows) + "\n")
    assert main(["simulate", str(model_path), str(tmp_path / "jitter.csv"), "-o", str(tmp_path / "y.csv")]) == 0
    np.testing.assert_allclose(read_table(tmp_path / "y.csv").values, g.simulate(u), atol=1e-12)
    del rows[51]  # drop data row 50
    (tmp_path / "gap.csv").write_text("\n".join(rows) + "\n")
    rc, out, err = run_main("simulate", model_path, tmp_path / "gap.csv", "-o", tmp_path / "y2.csv")
    assert_one_line_error(rc, err)
    assert not (tmp_path / "y2.csv").exists()


# ----------------------------------------------------------------- regressions of the bug hunt
_CHIRP = ["signal", "chirp", "--f0", "1", "--f1", "10", "--duration", "1", "--dt", "0.01"]


@pytest.mark.parametrize(
    "args, fragment",
    [
        (
            ["signal", "prbs", "--n-samples", "100", "--seed", "-1", "-o", "o.csv"],
            "'--seed': -1 is not in the range x>=0",
        ),
        (
            [
                "signal",
                "random",
                "--n-samples",
                "100",
                "--dt",
                "0.01",
                "--f-low",
                "1",
                "--f-high",
                "10",
                "--seed",
                "-1",
                "-o",
                "o.csv",
            ],
            "'--seed': -1 is not in the range x>=0",
        ),
        (
            ["plants", "p558", "--experiment", "chirp-z", "--seed", "-1", "-o", "o.csv"],
            "'--seed': -1 is not in the range x>=0",
        ),
        ([*_CHIRP, "-o", "o.mat"], "output 'o.mat' has extension '.mat'; expected .csv or .npz for a table"),
        ([*_CHIRP, "-o", "o"], "output 'o' has no extension; expected .csv or .npz"),
        (["plants", "p558", "-o", "m.npz"], "output 'm.npz' has extension '.npz'; expected .json for a model"),
        (["plants", "p558", "--experiment", "chirp-z", "-o", "e.json"], "expected .csv or .npz for a table"),
        (
            ["signal", "prbs", "--n-samples", "100", "--name", "Z;1", "-o", "s.csv"],
            "column name 'Z;1' would not read back from CSV",
        ),
        (["signal", "prbs", "--n-samples", "100", "--name", "a\tb", "-o", "s.csv"], "would not read back from CSV"),
        (["plants", "p558", "-o", "nodir/x.json"], "cannot write 'nodir/x.json': directory 'nodir' does not exist."),
        (["plants", "maglev", "--controller", "-o", "nodir/K.json"], "directory 'nodir' does not exist"),
        ([*_CHIRP, "-o", "nodir/c.csv"], "directory 'nodir' does not exist"),
        ([*_CHIRP, "--name", "t", "-o", "c.csv"], "--name 't' is reserved for the time column"),
        (
            ["signal", "sine", "--freq", "50", "--dt", "0.01", "--duration", "1", "-o", "s.csv"],
            "must be below the Nyquist frequency 1/(2 dt) = 50 Hz; got 50 Hz",
        ),
        ([*_CHIRP, "-o", "-"], "-o '-' (standard output) is not supported"),
        (
            [
                "signal",
                "decaying-sine",
                "--freq",
                "1",
                "--n-cycles",
                "2",
                "--dt",
                "0.01",
                "--amplitude",
                "1e308",
                "--offset",
                "1e308",
                "-o",
                "d.csv",
            ],
            "beyond the largest float",
        ),
    ],
)
def test_output_and_parameter_errors_are_one_line_and_leave_nothing(tmp_path, monkeypatch, args, fragment):
    monkeypatch.chdir(tmp_path)
    rc, out, err = run_main(*args)
    assert rc == 2, err
    assert_one_line_error(rc, err)
    assert fragment in err
    assert list(tmp_path.iterdir()) == []  # no output, no file named '-', no temporary file


def test_table_outputs_follow_the_extension(tmp_path, discrete_model, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _, model_path = discrete_model
    assert run_main(*_CHIRP, "--name", "Z", "-o", "z.npz")[0] == 0
    assert (tmp_path / "z.npz").read_bytes()[:2] == b"PK"  # a zip archive, not CSV text
    table = read_table(tmp_path / "z.npz")
    assert table.names == ("Z",) and table.n_samples == 100
    assert run_main("freqresp", model_path, "--fmin", "1", "--fmax", "100", "--n", "20", "-o", "fr.npz")[0] == 0
    with np.load(tmp_path / "fr.npz") as fr:
        assert fr["f_hz"].shape == (20,) and "re_z_Z" in fr.files
    assert run_main("freqresp", model_path, "--fmin", "1", "--fmax", "100", "--n", "20", "-o", "fr.csv")[0] == 0
    assert (tmp_path / "fr.csv").read_text().startswith("f_hz,")
    assert run_main("plants", "p558", "-o", "p558.json")[0] == 0
    assert json.loads((tmp_path / "p558.json").read_text())["format"] == "stageid.lti/1"
    assert run_main("signal", "prbs", "--n-samples", "50", "--dt", "0.01", "--name", "Z;1", "-o", "ok.csv")[0] == 0
    assert read_table(tmp_path / "ok.csv").names == ("Z;1",)  # with a `t` column the name reads back


def test_epoch_time_stamps_at_10_khz_are_accepted(tmp_path):
    # float64 rounding of t ~ 1.7e9 s scatters the steps by 2.4e-7 s, 0.24 % of dt: not clock jitter
    g = StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=1e-4, inputs=("Z",), outputs=("z",))
    save_model(g, tmp_path / "g.json")
    n = 2000
    u = np.random.default_rng(16).standard_normal(n)
    write_csv(tmp_path / "epoch.csv", {"t": 1.7e9 + 1e-4 * np.arange(n), "Z": u})
    rc, out, err = run_main("simulate", tmp_path / "g.json", tmp_path / "epoch.csv", "-o", tmp_path / "y.csv")
    assert rc == 0, err
    y = read_table(tmp_path / "y.csv")
    assert y.t0 == 1.7e9 and y.n_samples == n
    np.testing.assert_allclose(y.column("z"), g.simulate(u[:, None])[:, 0], rtol=0, atol=1e-12)
