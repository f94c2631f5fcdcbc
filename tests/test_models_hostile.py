"""Hostile model files and models at their limits: one line naming the problem, never an internal error.

Refused in the model loader and the model classes (one rule for numbers,
:func:`stageid.checks.is_real`): before, a ragged or nested ``A``, 100 000 nested brackets or a
long integer ended as "internal error" (exit 3), ``true`` and ``"0.5"`` were accepted as matrix
entries while ``"dt": "0.002"`` was refused, a time step of 1e-320 made the frequency response
fail in the solver, an unstable simulation was reported as "column 'y1' has inf", and numpy
``RuntimeWarning`` lines reached stderr.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from stageid import ModelError, ModelFormatError
from stageid.cli.main import main
from stageid.data import write_csv
from stageid.models import StateSpaceModel, TransferMatrix, loads, save_model

_SS = {
    "format": "stageid.lti/1",
    "kind": "statespace",
    "dt": 0.002,
    "A": [[0.5]],
    "B": [[1.0]],
    "C": [[1.0]],
    "D": [[0.0]],
}


def _text(**change: object) -> str:
    return json.dumps({**_SS, **change})


# name -> (file text, words the one-line message must hold)
HOSTILE = {
    "ragged A": (_text(A=[[0.5, 0.1], [0.2]], B=[[1.0], [0.0]], C=[[1.0, 0.0]]), "`A` must be a 2-D array"),
    "nested ragged A": (_text(A=[[0.5, [1.0]]]), "`A` must be a 2-D array"),
    "ragged D": (_text(D=[[0.0], [1.0, 2.0]]), "`D` must be a 2-D array"),
    "100 000 brackets": ('{"format": "stageid.lti/1", "A": ' + "[" * 100_000 + "]" * 100_000 + "}", "nests"),
    "5000-digit integer": (_text().replace('"A": [[0.5]]', '"A": [[' + "9" * 5000 + "]]"), "4300 digits"),
    "4000-digit integer": (_text().replace('"A": [[0.5]]', '"A": [[' + "9" * 4000 + "]]"), "not a finite real"),
    "4000-digit dt": (_text().replace('"dt": 0.002', '"dt": ' + "9" * 4000), "`dt` must be"),
    "boolean entry": (_text(A=[[True]]), "entry [0][0] is True"),
    "quoted entry": (_text(A=[["0.5"]]), "entry [0][0] is '0.5'"),
    "quoted coefficient": (
        json.dumps({"format": "stageid.lti/1", "kind": "transfer", "dt": None, "num": [[["1"]]], "den": [[[1, 1]]]}),
        "`num[0][0]` must be a list of numbers",
    ),
    "quoted dt": (_text(dt="0.002"), "`dt` must be"),
    "dt 1e-320": (_text(dt=1e-320), "finite sampling rate"),
}


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_hostile_model_file_is_one_format_error(name: str) -> None:
    text, words = HOSTILE[name]
    with pytest.raises(ModelFormatError) as info:
        loads(text)
    message = str(info.value)
    assert words in message and "\n" not in message and len(message) < 300, message


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_hostile_model_file_through_the_cli(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text, words = HOSTILE[name]
    model, out = tmp_path / "m.json", tmp_path / "fr.csv"
    model.write_text(text)
    rc = main(["freqresp", str(model), "--fmin", "1", "--fmax", "100", "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists(), err
    assert len(err.splitlines()) == 1 and words in err and "internal error" not in err, err


def test_one_rule_for_numbers_in_the_python_api() -> None:
    # the rule that refused "dt": "0.002" now refuses booleans and quoted numbers everywhere
    for bad in ([[True]], [["0.5"]], np.array([[True]])):
        with pytest.raises(ModelError, match="`A` must be"):
            StateSpaceModel(bad, [[1.0]], [[1.0]], [[0.0]], dt=0.1)
    with pytest.raises(ModelError, match="`dt` must be"):
        StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=True)
    with pytest.raises(ModelError, match="`num\\[0\\]\\[0\\]` must be a list of numbers"):
        TransferMatrix([[[False, 1.0]]], [[[1.0, 1.0]]])
    # integers, numpy scalars and arrays stay numbers
    g = StateSpaceModel([[np.float32(0.5)]], np.ones((1, 1), dtype=int), [[1]], [[0]], dt=0.1)
    assert g.A.dtype == float and float(g.dc_gain()[0, 0]) == 2.0


def test_tiny_time_step_is_named_not_a_solver_failure() -> None:
    g = StateSpaceModel([[-1.0, 0.0], [1.0, -2.0]], [[1.0], [0.0]], [[0.0, 1.0]], [[0.0]])
    with pytest.raises(ModelError, match="finite sampling rate 1/dt"):
        g.c2d(1e-320)
    with pytest.raises(ModelError, match="finite sampling rate 1/dt"):
        g.simulate(np.ones((10, 1)), dt=1e-320)


def test_frequency_response_at_an_exact_pole_is_infinite_not_a_solver_error() -> None:
    integrator = StateSpaceModel([[1.0]], [[1.0]], [[1.0]], [[0.0]], dt=0.01)  # pole at z = 1, i.e. 0 Hz
    G = integrator.frequency_response([0.0, 1.0])
    assert np.isinf(G[0, 0, 0]) and np.isfinite(G[1, 0, 0])


def _unstable_file(tmp_path: Path) -> Path:
    path = tmp_path / "unstable.json"
    save_model(StateSpaceModel([[1.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.002, inputs=("u1",), outputs=("y1",)), path)
    return path


def test_simulating_an_unstable_model_says_where_it_diverged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = _unstable_file(tmp_path)
    n = 5000  # 1.5^k overflows near k = 1750
    write_csv(tmp_path / "u.csv", {"u1": np.ones(n)}, dt=0.002)
    out = tmp_path / "y.csv"
    rc = main(["simulate", str(model), str(tmp_path / "u.csv"), "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "unstable" in err and "diverged at sample 1749 of 5000" in err, err
    # the same through the Python API, also on the short (non-compiled) path and for a transfer matrix
    g = StateSpaceModel([[1.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.002)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelError, match="diverged at sample 1749 of 1900: the model is unstable"):
            g.simulate(np.ones(1900))
        with pytest.raises(ModelError, match="diverged at sample 1749 of 1900: the model is unstable"):
            g.to_transfer().simulate(np.ones(1900))


def test_report_on_an_unstable_model_prints_no_numpy_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = _unstable_file(tmp_path)
    n = 1500  # 1.5^1500 ~ 1e264: finite, but its squares overflow in the fit
    write_csv(tmp_path / "d.csv", {"u1": np.ones(n), "y1": np.sin(np.arange(n) * 0.01)}, dt=0.002)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning would turn into an internal error
        rc = main(["report", str(model), str(tmp_path / "d.csv"), "--out", str(tmp_path / "rep")])
    err = capsys.readouterr().err
    assert rc == 0 and err == "", err
    fit = json.loads((tmp_path / "rep" / "metrics.json").read_text())["fit_percent/d.csv/y1"]
    assert fit is not None and fit < -1e200  # a hopeless fit, computed without overflow


def test_high_order_frequency_response_without_overflow(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poles = -np.arange(1, 51) * 100.0  # 50th order: s^50 overflows above ~1.5 MHz
    g = TransferMatrix([[[1e300]]], [[np.poly(poles)]], None, ("u1",), ("y1",))  # |G| ~ 1e-38 at 10 MHz
    f = np.geomspace(1.0, 1e7, 300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        G = g.frequency_response(f)[:, 0, 0]
    s = 2j * np.pi * f
    exact = np.exp(np.log(1e300) - np.sum(np.log(s[:, None] - poles[None, :]), axis=1))  # factored, in logs
    assert np.all(np.isfinite(G))
    np.testing.assert_allclose(G[f > 1e6], exact[f > 1e6], rtol=1e-9)  # where the plain form overflowed
    path, out = tmp_path / "hi.json", tmp_path / "fr.csv"
    save_model(g, path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rc = main(["freqresp", str(path), "--fmin", "1", "--fmax", "1e7", "-o", str(out)])
    assert rc == 0 and out.exists() and capsys.readouterr().err == ""
