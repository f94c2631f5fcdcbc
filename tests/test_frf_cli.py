"""`stageid frf` and `stageid identify frd` under the CLI contract: outputs as the API computes
them, and bad input -> exit 2, one line on stderr, no file."""

import contextlib
import io
import json

import numpy as np
import pytest

from stageid.cli.main import main
from stageid.data import Experiment, write_csv
from stageid.frf import FRDIdentification, FrequencyResponse, read_frd, welch_frf
from stageid.models import StateSpaceModel, load_model

DT = 1e-3
G = StateSpaceModel(
    [[1.6, -0.8], [1.0, 0.0]], [[1.0], [0.0]], [[0.1, 0.05]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",)
)


def run(*args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in args])
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture
def record(tmp_path):
    rng = np.random.default_rng(0)
    u = rng.standard_normal(20000)
    y = G.simulate(u[:, None])[:, 0] + 0.01 * rng.standard_normal(20000)
    write_csv(tmp_path / "rec.csv", {"u": u, "y": y}, dt=DT)
    return tmp_path / "rec.csv", u, y


def test_frf_welch_matches_the_api_and_prints_the_segment(tmp_path, record):
    path, u, y = record
    rc, out, err = run("frf", path, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "frf.csv")
    assert rc == 0, err
    assert "segment 2048 samples (chosen from the record" in out
    frd = read_frd(tmp_path / "frf.csv")
    api = welch_frf(Experiment(u, y, DT, ("u",), ("y",)))
    np.testing.assert_allclose(frd.response, api.response, rtol=1e-12)
    header = (tmp_path / "frf.csv").read_text().splitlines()[0]
    assert header == "f_hz,re_y_u,im_y_u,std_y_u,coh_y"


@pytest.mark.parametrize(
    "extra", [["--method", "lpm"], ["--segment", "500", "--overlap", "0.25", "--window", "hamming"]]
)
def test_frf_methods_write_npz(tmp_path, record, extra):
    path, *_ = record
    rc, _, err = run("frf", path, "--inputs", "u", "--outputs", "y", *extra, "-o", tmp_path / "frf.npz")
    assert rc == 0, err
    frd = read_frd(tmp_path / "frf.npz")
    # the std covers the error at 3 sigma almost everywhere (a calibrated std, coarse check)
    assert np.mean(np.abs(frd.response - G.frequency_response(frd.freqs)) < 3 * frd.std + 1e-9) > 0.9


def test_frf_periodic(tmp_path):
    from stageid.signals import multisine

    u = np.asarray(multisine(6000, DT, 1.0, 200.0, seed=1, n_periods=6))
    write_csv(tmp_path / "ms.csv", {"u": u, "y": G.simulate(u[:, None])[:, 0]}, dt=DT)
    args = ["frf", tmp_path / "ms.csv", "--inputs", "u", "--outputs", "y", "--method", "periodic"]
    rc, _, err = run(*args, "--periods", "6", "--transient-periods", "2", "-o", tmp_path / "p.csv")
    assert rc == 0, err
    frd = read_frd(tmp_path / "p.csv")
    assert frd.n_freqs == 200
    assert np.max(np.abs(frd.response - G.frequency_response(frd.freqs))) < 1e-6  # poles at 0.89: transient gone


def test_identify_frd_discrete_continuous_and_report(tmp_path, record):
    path, *_ = record
    assert run("frf", path, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "frf.csv")[0] == 0
    rc, out, err = run(
        "identify",
        "frd",
        tmp_path / "frf.csv",
        "--order",
        "2",
        "--dt",
        DT,
        "--report",
        tmp_path / "rep",
        "-o",
        tmp_path / "m.json",
    )
    assert rc == 0, err
    model = json.loads((tmp_path / "m.json").read_text())
    assert model["dt"] == DT and model["inputs"] == ["u"] and model["outputs"] == ["y"]
    assert (tmp_path / "rep" / "index.html").exists() and "order 2" in out
    frd = read_frd(tmp_path / "frf.csv")
    f, peak = frd.freqs, np.max(np.abs(G.frequency_response(frd.freqs)))
    fitted = load_model(tmp_path / "m.json")
    # the file holds the API's fit of the same FRF, and that fit recovers G: 0.075 % of the peak
    # seen, from data 0.65 % off (Welch noise and leakage)
    api = FRDIdentification(order=2, sample_time=DT).fit(frd).model
    np.testing.assert_allclose(fitted.frequency_response(f), api.frequency_response(f), rtol=1e-10, atol=0)
    assert np.max(np.abs(fitted.frequency_response(f) - G.frequency_response(f))) < 3e-3 * peak
    rc, _, err = run(
        "identify",
        "frd",
        tmp_path / "frf.csv",
        "--order",
        "auto",
        "--continuous",
        "--fmax",
        "100",
        "-o",
        tmp_path / "c.json",
    )
    assert rc == 0, err
    assert json.loads((tmp_path / "c.json").read_text())["dt"] is None
    band = f <= 100.0
    continuous = load_model(tmp_path / "c.json").frequency_response(f[band])
    api = FRDIdentification(order="auto", band=(None, 100.0)).fit(frd).model
    np.testing.assert_allclose(continuous, api.frequency_response(f[band]), rtol=1e-10, atol=0)
    assert np.max(np.abs(continuous - G.frequency_response(f[band]))) < 5e-3 * peak  # 0.15 % seen


def _write(tmp_path, name, text):
    (tmp_path / name).write_text(text)
    return tmp_path / name


def _bad_frf_cases(tmp_path, record):
    path, u, _ = record
    n = 100
    rng = np.random.default_rng(1)
    write_csv(tmp_path / "short.csv", {"u": u[:n], "y": u[:n]}, dt=DT)
    write_csv(tmp_path / "const.csv", {"u": np.ones(5000), "y": rng.standard_normal(5000)}, dt=DT)
    w = rng.standard_normal(5000)
    write_csv(tmp_path / "equal.csv", {"u1": w, "u2": w, "y": rng.standard_normal(5000)}, dt=DT)
    _write(tmp_path, "nan.csv", "t,u,y\n0,1,2\n0.001,nan,1\n0.002,1,1\n")
    return [
        (
            ["frf", tmp_path / "short.csv", "--inputs", "u", "--outputs", "y", "--segment", "256"],
            "fewer than one segment",
        ),
        (["frf", tmp_path / "const.csv", "--inputs", "u", "--outputs", "y", "--segment", "256"], "singular"),
        (["frf", tmp_path / "equal.csv", "--inputs", "u1,u2", "--outputs", "y", "--segment", "256"], "proportional"),
        (["frf", tmp_path / "nan.csv", "--inputs", "u", "--outputs", "y"], "NaN"),
        (
            ["frf", path, "--inputs", "u", "--outputs", "y", "--method", "lpm", "--segment", "64"],
            "--segment applies to --method welch",
        ),
        (["frf", path, "--inputs", "u", "--outputs", "y", "--method", "periodic"], "needs --periods"),
    ]


def test_bad_records_exit_2_one_line_no_file(tmp_path, record):
    for args, fragment in _bad_frf_cases(tmp_path, record):
        target = tmp_path / "out.csv"
        rc, out, err = run(*args, "-o", target)
        assert rc == 2 and fragment in err and err.count("\n") == 1 and not out, (args, err)
        assert not target.exists()


@pytest.mark.parametrize(
    "table, extra, fragment",
    [
        ("f_hz,re_y_u,im_y_u\n1,1,0\n3,1,0\n2,1,0\n", ["--dt", "0.001"], "strictly increasing"),
        ("f_hz,re_y_u\n1,1\n2,1\n", ["--dt", "0.001"], "no matching 'im_y_u'"),
        ("f_hz,re_y_u,im_y_u\n1,1,0\n2,nan,0\n", ["--dt", "0.001"], "NaN"),
        ("f_hz,re_y_u,im_y_u\n1,1,0\n2,1,0\n", [], "give --dt S for a discrete model or --continuous"),
        ("f_hz,re_y_u,im_y_u\n1,1,0\n2,1,0\n", ["--dt", "0.001", "--continuous"], "not both"),
        ("f_hz,re_y_u,im_y_u\n1,1,0\n2,1,0\n", ["--continuous", "--order", "x"], "integer or 'auto'"),
    ],
)
def test_identify_frd_bad_input(tmp_path, table, extra, fragment):
    path = _write(tmp_path, "f.csv", table)
    rc, out, err = run("identify", "frd", path, *extra, "-o", tmp_path / "m.json")
    assert rc == 2 and fragment in err and err.count("\n") == 1, err
    assert not (tmp_path / "m.json").exists()


def test_npz_records_streamed_with_the_same_result_and_checks(tmp_path, record):
    path, u, y = record
    np.savez(tmp_path / "rec.npz", t=np.arange(u.size) * DT, u=u, y=y)
    assert run("frf", path, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "a.csv")[0] == 0
    assert run("frf", tmp_path / "rec.npz", "--inputs", "u", "--outputs", "y", "-o", tmp_path / "b.csv")[0] == 0
    np.testing.assert_allclose(read_frd(tmp_path / "b.csv").response, read_frd(tmp_path / "a.csv").response, rtol=1e-12)
    np.savez_compressed(tmp_path / "z.npz", t=np.arange(u.size) * DT, u=u, y=y)  # read through the zip reader
    assert run("frf", tmp_path / "z.npz", "--inputs", "u", "--outputs", "y", "-o", tmp_path / "z.csv")[0] == 0
    np.testing.assert_allclose(read_frd(tmp_path / "z.csv").response, read_frd(tmp_path / "a.csv").response, rtol=1e-12)
    for k, name in ((5000, "u"), (u.size - 3, "y")):  # inside a segment, and in the tail after the last one
        bad = {"u": u.copy(), "y": y.copy()}
        bad[name][k] = np.nan
        np.savez(tmp_path / "nan.npz", t=np.arange(u.size) * DT, **bad)
        rc, _, err = run(
            "frf",
            tmp_path / "nan.npz",
            "--inputs",
            "u",
            "--outputs",
            "y",
            "--segment",
            "1000",
            "-o",
            tmp_path / "c.csv",
        )
        assert rc == 2 and f"column '{name}' has NaN at row {k}" in err and err.count("\n") == 1, err
        assert not (tmp_path / "c.csv").exists()


@pytest.mark.parametrize(
    "args, bad, fragment",
    [
        (["frf", "missing.csv", "--inputs", "u", "--outputs", "y"], "out.json", "expected .csv or .npz for a table"),
        (["identify", "frd", "missing.csv", "--dt", "0.001"], "out.csv", "expected .json for a model"),
        (["identify", "frd", "missing.csv", "--dt", "0.001", "--report", "nodir/rep"], "m.json", "does not exist"),
    ],
)
def test_bad_output_refused_before_any_reading(tmp_path, monkeypatch, args, bad, fragment):
    monkeypatch.chdir(tmp_path)  # the input does not exist: the output check must come first
    rc, out, err = run(*args, "-o", bad)
    assert rc == 2 and fragment in err and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


def test_identify_frd_words_the_fit_s_refusals_in_its_own_flags(tmp_path):
    f = np.linspace(1.0, 400.0, 200)
    write_csv(tmp_path / "frf.csv", FrequencyResponse(f, G.frequency_response(f)).to_columns(), dt=None)
    # the response reaches 400 Hz, above the Nyquist frequency of --dt 0.01
    rc, _, err = run("identify", "frd", tmp_path / "frf.csv", "--order", "2", "--dt", "0.01", "-o", tmp_path / "m.json")
    assert rc == 2 and "end the band below it (--fmax) or give a smaller --dt." in err and "`" not in err
    rc, _, err = run("identify", "frd", tmp_path / "frf.csv", "--dt", "0.01", "--fmax", "80", "-o", tmp_path / "m.json")
    assert rc == 2 and "--fmax" in err and "must be at most the Nyquist frequency 50 Hz of --dt; got 80." in err
