"""The stageid.lti/1 format: byte-stable round trips and field-naming errors."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from stageid import ModelFormatError
from stageid.models import StateSpaceModel, TransferMatrix, dumps, load_model, loads, save_model

finite = st.floats(allow_nan=False, allow_infinity=False, width=64, min_value=-1e300, max_value=1e300)


@st.composite
def statespace_models(draw):
    n = draw(st.integers(0, 4))
    m = draw(st.integers(1, 3))
    p = draw(st.integers(1, 3))
    dt = draw(st.one_of(st.none(), st.floats(1e-6, 10.0)))
    mats = [draw(arrays(float, shape, elements=finite)) for shape in ((n, n), (n, m), (p, n), (p, m))]
    names = st.text(alphabet="abcxyzXYZ_019", min_size=1, max_size=6)
    inputs = draw(st.lists(names, min_size=m, max_size=m, unique=True))
    outputs = draw(st.lists(names, min_size=p, max_size=p, unique=True))
    return StateSpaceModel(*mats, dt=dt, inputs=tuple(inputs), outputs=tuple(outputs))


@given(statespace_models())
@settings(max_examples=60, deadline=None)
def test_statespace_round_trip_is_byte_stable(model):
    text = model.to_json()
    back = loads(text)
    assert back.to_json() == text
    for name in "ABCD":
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    assert back.dt == model.dt and back.inputs == model.inputs and back.outputs == model.outputs


@st.composite
def transfer_models(draw):
    m = draw(st.integers(1, 2))
    p = draw(st.integers(1, 2))
    coeffs = st.floats(-1e6, 1e6, allow_nan=False)
    num, den = [], []
    for _ in range(p):
        nrow, drow = [], []
        for _ in range(m):
            order = draw(st.integers(0, 3))
            d = [draw(st.floats(0.5, 2.0))] + draw(st.lists(coeffs, min_size=order, max_size=order))
            nrow.append(draw(st.lists(coeffs, min_size=1, max_size=order + 1)))
            drow.append(d)
        num.append(nrow)
        den.append(drow)
    dt = draw(st.one_of(st.none(), st.floats(1e-5, 1.0)))
    return TransferMatrix(num, den, dt)


@given(transfer_models())
@settings(max_examples=60, deadline=None)
def test_transfer_round_trip_is_byte_stable(model):
    text = model.to_json()
    assert loads(text).to_json() == text


def test_file_layout_matches_the_contract(tmp_path):
    g = StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.002, inputs=("Z",), outputs=("z",))
    path = tmp_path / "m.json"
    save_model(g, path)
    d = json.loads(path.read_text())
    assert list(d) == ["format", "kind", "dt", "A", "B", "C", "D", "inputs", "outputs"]
    assert d["format"] == "stageid.lti/1" and d["kind"] == "statespace" and d["dt"] == 0.002
    assert load_model(path).to_json() == path.read_text()
    t = TransferMatrix([[[1.0]]], [[[1.0, 1.0]]])
    assert list(t.to_dict()) == ["format", "kind", "dt", "num", "den", "inputs", "outputs"]
    assert t.to_dict()["dt"] is None


def _ss_dict():
    return {
        "format": "stageid.lti/1",
        "kind": "statespace",
        "dt": None,
        "A": np.eye(15).tolist(),
        "B": np.ones((15, 3)).tolist(),
        "C": np.ones((3, 15)).tolist(),
        "D": np.zeros((3, 3)).tolist(),
        "inputs": ["Z", "Rx", "Ry"],
        "outputs": ["z", "rx", "ry"],
    }


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.update(B=np.ones((5, 3)).tolist()), r"`B` must have shape \(15, 3\); got \(5, 3\)"),
        (lambda d: d.update(C=np.ones((3, 14)).tolist()), r"`C` must have shape \(3, 15\); got \(3, 14\)"),
        (lambda d: d.pop("A"), r"`A` is missing"),
        (lambda d: d.update(A="eye"), r"`A` must be a 2-D array of numbers"),
        (lambda d: d.update(D=[[0, 0, "x"]] * 3), r"`D` must be a 2-D array of numbers"),
        (lambda d: d.update(dt=-1), r"`dt` must be null"),
        (lambda d: d.update(kind="zpk"), r"`kind` must be"),
        (lambda d: d.update(format="other/1"), r"unknown model format"),
        (lambda d: d.update(inputs=["Z", "Rx"]), r"`B` must have shape \(15, 2\); got \(15, 3\)"),
    ],
)
def test_malformed_files_name_the_field(change, message):
    d = _ss_dict()
    change(d)
    with pytest.raises(ModelFormatError, match=message):
        loads(json.dumps(d))


def test_transfer_errors_name_the_entry():
    d = {"format": "stageid.lti/1", "kind": "transfer", "dt": None, "num": [[[1.0, 2.0, 3.0]]], "den": [[[1.0, 1.0]]]}
    with pytest.raises(ModelFormatError, match=r"entry \[0\]\[0\] is improper"):
        loads(json.dumps(d))
    d["num"] = [[[1.0], [1.0]]]
    with pytest.raises(ModelFormatError, match=r"`den` must have shape \(1, 2\)"):
        loads(json.dumps(d))


def test_not_json_and_missing_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ModelFormatError, match="not valid JSON"):
        load_model(bad)
    with pytest.raises(ModelFormatError, match="does not exist"):
        load_model(tmp_path / "nope.json")


def test_dumps_rejects_non_finite():
    with pytest.raises(ModelFormatError, match="finite"):
        dumps({"x": [float("nan")]})
