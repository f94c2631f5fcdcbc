"""One contract for every estimator: configure, fit, get an immutable result (STYLE.md).

- ``__init__`` stores its keyword hyper-parameters unchanged and does no work;
- ``fit`` never modifies the caller's data and returns a frozen result;
- a second ``fit`` on other data gives an independent result (the first is unchanged).
"""

import dataclasses
import inspect
import json

import numpy as np
import pytest

from stageid.closedloop import ClosedLoopIdentification
from stageid.data import Experiment
from stageid.hysteresis import PIIdentifier
from stageid.models import StateSpaceModel
from stageid.subspace import HankelMAP


def _siso_data(seed):
    rng = np.random.default_rng(seed)
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=0.01)
    u = rng.standard_normal((3000, 1))
    return Experiment(u, g.simulate(u) + 1e-3 * rng.standard_normal((3000, 1)), 0.01, ("u",), ("y",))


def _hysteresis_data(seed):
    from stageid.plants.piezo_actuator import EXPERIMENTS

    # the reference actuator is noise-free, so a different seed alone would give the same record
    return EXPERIMENTS["decaying-triangle" if seed == 0 else "decaying-sine"](seed=seed)


def _closed_loop_data(seed):
    # an unstable first-order plant under a proportional controller; the reference is the input
    rng = np.random.default_rng(seed)
    G = StateSpaceModel([[1.02]], [[0.05]], [[1.0]], [[0.0]], dt=0.001)  # unstable
    K = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], dt=0.001)
    from stageid.models import feedback

    cl = feedback(G, K)
    r = rng.standard_normal((4000, 1))
    r[:100] = 0.0  # the loop starts at rest, as real records do
    yu = cl.simulate(r)
    return Experiment(r, yu[:, :1] + 1e-5 * rng.standard_normal((4000, 1)), 0.001, ("r_y",), ("y",)), K


CASES = {
    "HankelMAP": (lambda: HankelMAP(horizon=8, order=2), _siso_data),
    "PIIdentifier": (lambda: PIIdentifier("pi", n_operators=8), _hysteresis_data),
}


@pytest.mark.parametrize("name", list(CASES))
def test_init_stores_parameters_unchanged(name):
    make, _ = CASES[name]
    est = make()
    params = inspect.signature(type(est).__init__).parameters
    for p in params:
        if p == "self":
            continue
        assert hasattr(est, p), f"{name} must store `{p}` as an attribute of the same name"


@pytest.mark.parametrize("name", list(CASES))
def test_fit_keeps_caller_data_and_returns_frozen_result(name):
    make, data = CASES[name]
    est = make()
    exp = data(0)
    u_before, y_before = exp.u.copy(), exp.y.copy()
    result = est.fit(exp)
    np.testing.assert_array_equal(exp.u, u_before)
    np.testing.assert_array_equal(exp.y, y_before)
    assert dataclasses.is_dataclass(result)
    field = dataclasses.fields(result)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(result, field, None)
    before = json.dumps(result.model.to_dict())
    second = est.fit(data(1))
    assert json.dumps(result.model.to_dict()) == before  # the first result is untouched by a second fit
    assert json.dumps(second.model.to_dict()) != before  # and the second fit really used the new data


def test_closed_loop_estimator_contract():
    exp, K = _closed_loop_data(0)
    est = ClosedLoopIdentification(K, orders=1, structure="full", band=(1.0, 100.0))
    assert est.controller is K and est.orders == 1
    r_before = exp.u.copy()
    result = est.fit(exp)
    np.testing.assert_array_equal(exp.u, r_before)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.plant = None
    # the unstable pole at z = 1.02 (s = ln(1.02)/dt) is recovered from closed-loop data
    s_true = np.log(1.02) / 0.001
    assert np.min(np.abs(np.asarray(result.unstable_poles) - s_true)) < 0.05 * s_true
