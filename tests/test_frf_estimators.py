"""The nonparametric FRF estimators as contract classes: the functions are their thin wrappers.

``welch_frf``, ``lpm_frf`` and ``periodic_frf`` return the ``model`` of :class:`WelchFRF`,
:class:`LocalPolynomialFRF` and :class:`PeriodicFRF`; the result keeps a copy of the settings
and says what the method decided from the data.
"""

import dataclasses

import numpy as np
import pytest

from stageid import ParameterError
from stageid.data import Experiment
from stageid.frf import (
    FRFResult,
    LocalPolynomialFRF,
    PeriodicFRF,
    WelchFRF,
    lpm_frf,
    periodic_frf,
    welch_frf,
)
from stageid.models import StateSpaceModel

DT = 0.01
PLANT = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=DT)


def _random(seed=0, n=4000):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 1))
    return Experiment(u, PLANT.simulate(u) + 1e-3 * rng.standard_normal((n, 1)), DT, ("u",), ("y",))


def _periodic(seed=0, period=250, periods=12):
    rng = np.random.default_rng(seed)
    u = np.tile(rng.standard_normal((period, 1)), (periods, 1))
    return Experiment(u, PLANT.simulate(u) + 1e-3 * rng.standard_normal(u.shape), DT, ("u",), ("y",))


def _same(a, b):
    for name in ("freqs", "response", "std", "coherence"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (a.inputs, a.outputs) == (b.inputs, b.outputs)


@pytest.mark.parametrize(
    "function, args, estimator, data",
    [
        (welch_frf, (256, 0.25, "hamming"), WelchFRF(segment=256, overlap=0.25, window="hamming"), _random),
        (welch_frf, (), WelchFRF(), _random),
        (lpm_frf, (1, 5), LocalPolynomialFRF(degree=1, half_width=5), _random),
        (periodic_frf, (12, 2), PeriodicFRF(periods=12, transient_periods=2), _periodic),
    ],
)
def test_function_is_the_estimators_model(function, args, estimator, data):
    exp = data()
    result = estimator.fit(exp)
    assert isinstance(result, FRFResult)
    _same(function(exp, *args), result.model)


def test_lpm_keyword_compiled_reaches_the_estimator():
    exp = _random(1)
    _same(lpm_frf(exp, compiled=False), LocalPolynomialFRF(compiled=False).fit(exp).model)


def test_diagnostics_say_what_the_method_decided():
    welch = WelchFRF().fit(_random(n=4000)).diagnostics
    # default_segment(4000): the largest power of two giving >= 16 half-overlapping segments
    assert welch["segment"] == 256 and welch["n_segments"] == (4000 - 256) // 128 + 1
    assert 0 < welch["effective_segments"] <= welch["n_segments"]
    lpm = LocalPolynomialFRF(degree=2).fit(_random()).diagnostics
    assert lpm["half_width"] == 6 and lpm["lines_left_out"] >= 0  # (1 + 1)(2 + 1) + 6 - 1 over 2, rounded up
    periodic = PeriodicFRF(periods=12, transient_periods=3).fit(_periodic()).diagnostics
    assert dict(periodic) == {"period": 250, "periods_averaged": 9}


def test_result_keeps_a_frozen_copy_of_the_settings():
    est = WelchFRF(segment=256)
    result = est.fit(_random())
    est.segment = 512  # changed after the fit: the result does not see it
    assert result.estimator.segment == 256 and result.estimator is not est
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.model = None
    with pytest.raises(TypeError):
        result.diagnostics["segment"] = 1
    text = result.summary()
    assert text.startswith("WelchFRF(segment=256): ") and "n_segments" in text
    assert repr(result).startswith("FRFResult(WelchFRF(segment=256), ")


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda exp: welch_frf(exp, segment=1), "`segment` of WelchFRF must be an integer >= 2 or None; got 1."),
        (lambda exp: welch_frf(exp, overlap=1.0), "`overlap` of WelchFRF must be "),
        (lambda exp: lpm_frf(exp, degree=7), "`degree` of LocalPolynomialFRF must be an integer "),
        (lambda exp: lpm_frf(exp, compiled=1), "`compiled` of LocalPolynomialFRF must be True or False; got 1."),
        (lambda exp: periodic_frf(exp, periods=0), "`periods` of PeriodicFRF must be an integer >= 1"),
    ],
)
def test_bad_settings_through_the_functions_are_one_parameter_error(call, message):
    with pytest.raises(ParameterError) as info:
        call(_random(n=500))
    assert str(info.value).startswith(message), str(info.value)
