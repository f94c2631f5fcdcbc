"""Tests written to kill survivors of the ``creep`` mutation group (tests/MUTATION.md)."""

import numpy as np
import pytest

from stageid import ModelFormatError
from stageid.hysteresis import CreepTerm


def _term(**kw):
    return CreepTerm(time_constants=[0.01, 0.5], weights=[0.2, 0.05], sample_time=1e-3, **kw)


def test_a_one_sample_input_gives_the_first_sample_of_a_longer_run():
    u = np.array([2.0, -1.0, 0.5])
    for term in (_term(), _term(state=[0.3, -0.2])):
        np.testing.assert_array_equal(term.lags(u[:1]), term.lags(u)[:1])
        y1, s1 = term.run(u[:1])
        y, _ = term.run(u)
        np.testing.assert_array_equal(y1, y[:1])
        np.testing.assert_array_equal(s1, term.lags(u)[0])
    # from rest at u[0], one sample leaves every lag at u[0]
    np.testing.assert_allclose(_term().lags([2.0]), [[2.0, 2.0]], rtol=1e-15)
    assert _term().lags([]).shape == (0, 2)


def test_from_dict_without_a_state_and_with_a_missing_field():
    d = {"time_constants": [0.01, 0.5], "weights": [0.2, 0.05], "sample_time": 1e-3}  # "state" is optional
    term = CreepTerm.from_dict(d)
    assert term.state is None and term.to_dict() == {**d, "state": None}
    for missing in d:
        with pytest.raises(ModelFormatError, match="time_constants, weights, sample_time"):
            CreepTerm.from_dict({k: v for k, v in d.items() if k != missing})
    with pytest.raises(ModelFormatError, match="time_constants, weights, sample_time"):
        CreepTerm.from_dict({**d, "extra": 1})
