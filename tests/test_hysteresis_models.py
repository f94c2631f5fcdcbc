"""PI and modified-PI model objects: simulation, state, immutability, JSON round trip."""

import dataclasses
import json

import numpy as np
import pytest

from stageid import ModelError, ModelFormatError
from stageid.hysteresis import ModifiedPIModel, PIModel
from stageid.models.serialization import dumps, loads


def _modified(rng, n=8):
    r = np.arange(n) * 50.0
    rc = r * 0.5
    ra = r * 1.4
    rb = ra * 0.6
    w = np.r_[1.0, rng.uniform(0.0, 0.3, n - 1)]
    return ModifiedPIModel(
        r=r,
        rc=rc,
        ra=ra,
        rb=rb,
        weights=w,
        input_offset=3.0,
        output_offset=-0.2,
        input_warp=0.1,
        warp_scale=350.0,
        inputs=("V",),
        outputs=("y",),
        input_limits=(-500.0, 500.0),
    )


def test_simulate_shapes_and_linear_term():
    m = PIModel(r=[0.0], weights=[2.0], output_offset=1.0)
    y = m.simulate(np.arange(5.0))
    assert y.shape == (5, 1)
    assert y[:, 0].tolist() == [1.0, 3.0, 5.0, 7.0, 9.0]
    assert m.simulate(np.arange(5.0)[:, None], dt=0.1).shape == (5, 1)


def test_modified_reduces_to_classical():
    rng = np.random.default_rng(0)
    u = np.cumsum(rng.normal(0, 20, 1000))
    pi = PIModel(r=[0.0, 10.0, 40.0], weights=[1.0, 0.5, -0.2])
    y = pi.simulate(u)
    # different kernels (event-driven play sum vs CP loop): rounding only, 1e-12 of the scale
    np.testing.assert_allclose(pi.to_modified().simulate(u), y, rtol=0, atol=1e-12 * np.abs(y).max())


def test_resume_from_state():
    m = _modified(np.random.default_rng(1))
    u = 400 * np.sin(np.linspace(0, 9, 900))
    y_all, s_all = m.run(u)
    y1, s1 = m.run(u[:400])
    y2, s2 = m.with_state(s1).run(u[400:])
    # the event-driven kernel sums along a different path after the split: rounding only
    np.testing.assert_allclose(np.vstack([y1, y2]), y_all, rtol=0, atol=1e-12 * np.abs(y_all).max())
    np.testing.assert_allclose(s2.z, s_all.z, rtol=0, atol=1e-12 * 400)


def test_immutable_and_inputs_untouched():
    m = _modified(np.random.default_rng(2))
    for name in ("r", "rc", "ra", "rb", "weights"):  # every array of the model is read-only
        with pytest.raises(ValueError, match="read-only"):
            getattr(m, name)[0] = 5.0
    for name in ("r", "weights", "input_offset", "input_warp"):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(m, name, 0.0)
    u = np.linspace(-100, 100, 50)
    before = u.copy()
    y0 = m.simulate(u)
    assert np.array_equal(u, before)
    # the model keeps copies: the caller's arrays stay writable and later writes do not reach it
    r, w = np.arange(4) * 50.0, np.array([1.0, 0.2, 0.1, 0.05])
    for cls in (PIModel, ModifiedPIModel):
        model = cls(r=r, weights=w)
        y = model.simulate(u)
        r[1] += 1.0
        w[0] = 7.0
        np.testing.assert_array_equal(model.simulate(u), y)
        assert not np.shares_memory(model.r, r) and not np.shares_memory(model.weights, w)
        r[1] -= 1.0
        w[0] = 1.0
    assert np.array_equal(m.simulate(u), y0)


@pytest.mark.parametrize("kind", ["pi", "modified"])
def test_json_round_trip_byte_stable(kind):
    rng = np.random.default_rng(3)
    m = (
        _modified(rng)
        if kind == "modified"
        else PIModel(r=[0.0, 0.1, 0.30000000000000004], weights=[1 / 3, 0.2, 1e-17])
    )
    u = 300 * np.sin(np.linspace(0, 5, 200))
    m = m.with_state(m.run(u)[1])  # a non-trivial state survives the round trip
    text = dumps(m.to_dict())
    back = loads(text)
    assert dumps(back.to_dict()) == text
    assert type(back) is type(m)
    np.testing.assert_array_equal(back.simulate(u), m.simulate(u))


def test_format_errors_name_the_field():
    m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    d = json.loads(dumps(m.to_dict()))
    bad = dict(d, weights=[1.0])
    with pytest.raises(ModelFormatError, match="weights"):
        loads(json.dumps(bad))
    with pytest.raises(ModelFormatError, match="kind"):
        loads(json.dumps(dict(d, kind="bouc-wen")))
    with pytest.raises(ModelFormatError, match="rc <= r"):
        md = json.loads(dumps(_modified(np.random.default_rng(0)).to_dict()))
        md["rc"][3] = 1e6
        loads(json.dumps(md))


def test_constructor_errors():
    with pytest.raises(ModelError, match="ascending"):
        PIModel(r=[1.0, 0.0], weights=[1.0, 1.0])
    with pytest.raises(ModelError, match="one input"):
        PIModel(r=[0.0], weights=[1.0], inputs=("a", "b"))
    with pytest.raises(ModelError, match="2 entries"):
        PIModel(r=[0.0, 1.0], weights=[1.0])


@pytest.mark.parametrize(
    "path, value",
    [
        (("weights", 1), True),
        (("weights", 1), "0.5"),
        (("r", 0), False),
        (("rc",), [[0.0, 1.0], [2.0]]),
        (("ra",), [0.0, [1.0]]),
        (("input_offset",), "0.5"),
        (("output_offset",), True),
        (("input_warp",), "0.1"),
        (("state", "x"), "1.0"),
        (("state", "z", 2), True),
        (("input_limits", 0), "-1"),
        (("weights", 0), 1e400),
    ],
)
def test_json_numbers_are_json_numbers(path, value):
    # a boolean or a quoted number was accepted as a weight or threshold while `"dt": "0.002"`
    # was refused; nested and ragged lists gave internal errors
    d = json.loads(dumps(_modified(np.random.default_rng(0)).to_dict()))
    d["input_limits"] = [-100.0, 100.0]
    target = d
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    field = ".".join(str(p) for p in path if isinstance(p, str))
    with pytest.raises(ModelFormatError, match=f"^`{field}` must be ") as info:
        loads(json.dumps(d))
    assert "\n" not in str(info.value) and len(str(info.value)) < 300


def test_plant_kinds_are_registered_by_the_plants():
    # the hysteresis loader does not import stageid.plants: the plant registers its kind, and a
    # file read before any plant module was imported (the command line) still loads
    import subprocess
    import sys

    from stageid.hysteresis.models.serialization import register_kind
    from stageid.plants.piezo_actuator import PiezoActuator, model

    act = model()
    assert isinstance(loads(dumps(act.to_dict())), PiezoActuator)
    with pytest.raises(ModelError, match="cannot be registered"):
        register_kind("pi", lambda d: d)
    bad = act.to_dict()
    bad["parameters"]["gain"] = "0.95"
    with pytest.raises(ModelFormatError, match=r"^`parameters.gain` must be a number"):
        loads(json.dumps(bad))
    code = (
        "import sys; from stageid.models.serialization import loads; "
        f"m = loads({dumps(act.to_dict())!r}); "
        "print(type(m).__name__, 'stageid.plants' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["PiezoActuator", "True"]
