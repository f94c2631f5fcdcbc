"""The reference piezo actuator: hysteresis %, asymmetry, rate independence, not a PI model."""

import numpy as np
import pytest

from stageid.data import Experiment
from stageid.hysteresis import PIIdentifier, hysteresis_percent
from stageid.plants import plant_module
from stageid.plants.piezo_actuator import EXPERIMENTS, PiezoActuator, model
from stageid.signals import triangle


def _major(act):
    u = triangle(1.0, 2.0, 1e-3, amplitude=500.0)
    return u, act.simulate(u)[:, 0]


def test_hysteresis_like_the_letter():
    u, y = _major(model())
    h = hysteresis_percent(u[1000:], y[1000:])
    assert 7.0 < h < 10.5  # the letter: 8.3 % (Fig. 10)
    assert 2.0 < np.ptp(y) < 6.0  # micrometres


def test_asymmetric_loop():
    u, y = _major(model())
    up = np.diff(u) > 0
    cycle = slice(1000, 2000)
    x = u[cycle]
    ys = y[cycle]
    rising = np.r_[up[cycle.start - 1 : cycle.stop - 1]]
    grid = np.linspace(-300, 300, 7)
    y_up = np.interp(grid, x[rising][np.argsort(x[rising])], ys[rising][np.argsort(x[rising])])
    y_dn = np.interp(grid, x[~rising][np.argsort(x[~rising])], ys[~rising][np.argsort(x[~rising])])
    centre = 0.5 * (y.max() + y.min())
    # a point-symmetric loop has y_up(x) - c = -(y_down(-x) - c)
    asym = np.max(np.abs((y_up - centre) + (y_dn[::-1] - centre))) / np.ptp(y)
    assert asym > 0.02


def test_rate_independent():
    act = model()
    t = np.linspace(0, 1, 2001)
    slow = 450 * np.sin(2 * np.pi * t)
    fast = 450 * np.sin(2 * np.pi * np.sqrt(t))  # same extrema, other timing
    ys, yf = act.simulate(slow)[:, 0], act.simulate(fast)[:, 0]
    for target in (450.0, -450.0):
        assert ys[np.argmin(np.abs(slow - target))] == pytest.approx(yf[np.argmin(np.abs(fast - target))], abs=1e-3)


def test_not_a_pi_model():
    exp = EXPERIMENTS["decaying-triangle"]()
    fit = PIIdentifier("pi", n_operators=20).fit(exp)
    assert fit.max_error_percent[0] > 3.0  # the letter's classical PI: 5.31 %


def test_experiments_and_registry():
    assert plant_module("piezo-actuator").model().inputs == ("V",)
    for make in EXPERIMENTS.values():
        exp = make(seed=1)
        assert isinstance(exp, Experiment) and exp.input_names == ("V",) and exp.output_names == ("y",)
        assert np.abs(exp.u).max() <= 500.0


def test_dynamics_option_keeps_dc_gain():
    act = PiezoActuator(f_n=200.0, zeta=0.5)
    u = np.r_[np.linspace(0, 300, 100), np.full(2000, 300.0)]
    y = act.simulate(u, dt=1e-4)[:, 0]
    static = model().simulate(u)[:, 0]
    assert y[-1] == pytest.approx(static[-1], rel=1e-6)
    assert not np.allclose(y[:150], static[:150])


def test_model_file_round_trip(tmp_path):
    from stageid.models import load_model
    from stageid.models.serialization import dumps, save_model

    act = PiezoActuator(quad=0.03, c=(0.3, 0.1), f_n=None)
    save_model(act, tmp_path / "act.json")
    back = load_model(tmp_path / "act.json")
    assert dumps(back.to_dict()) == (tmp_path / "act.json").read_text()
    u = triangle(1.0, 1.0, 1e-3, amplitude=400.0)
    np.testing.assert_array_equal(back.simulate(u), act.simulate(u))
