"""Two-stage and joint input-output routes on a recorded reference, and the routes' agreement.

Truth: :mod:`stageid.plants.levitated_pair` under its filtered PD (not told to the fits),
2 % measurement noise.
"""

import numpy as np
import pytest

from stageid import DataError, IdentificationError
from stageid.closedloop.direct import DirectPredictionError
from stageid.closedloop.joint import JointInputOutput
from stageid.closedloop.two_stage import TwoStageProjection
from stageid.closedloop.unknown_result import unstable_pole_agreement
from stageid.data import Experiment
from stageid.plants import levitated_pair as lp

BAND = np.geomspace(0.5, 50.0, 60)
NAMES = ("r1", "r2", "u1", "u2")


def _record(seed=1, **loop):
    r, u, y = lp.record(5000, seed=seed, **loop)
    return Experiment(np.hstack([r, u]), y, lp.DT, NAMES, ("x1", "x2"))


def _frf_error(result):
    true = lp.model().frequency_response(BAND)
    return np.abs(result.plant.frequency_response(BAND) - true).max() / np.abs(true).max()


@pytest.fixture(scope="module")
def linear_record():
    return _record()


def test_two_stage_finds_the_unstable_poles(linear_record):
    res = TwoStageProjection(order=4, sensitivity_order=8, references=["r1", "r2"]).fit(linear_record)
    np.testing.assert_allclose(np.sort(res.unstable_poles.real), lp.UNSTABLE_POLES, rtol=0.02)
    # only the reference-driven part of u informs the plant: a looser response than the direct route
    assert _frf_error(res) < 0.03
    assert {c.name: c for c in res.checks}["reference_share"].value > 0.9
    assert res.unstable_pole_std is not None and np.all(res.unstable_pole_std > 0)


def test_joint_cross_checks_the_unstable_poles(linear_record):
    res = JointInputOutput(order=8, references=["r1", "r2"]).fit(linear_record)
    np.testing.assert_allclose(np.sort(res.unstable_poles.real), lp.UNSTABLE_POLES, rtol=0.02)
    assert res.pole_std is None
    with pytest.raises(IdentificationError, match="no covariance"):
        res.response_uncertainty(BAND)


def test_routes_agree_on_a_linear_loop(linear_record):
    direct = DirectPredictionError(order=4, references=["r1", "r2"]).fit(linear_record)
    joint = JointInputOutput(order=8, references=["r1", "r2"]).fit(linear_record)
    agree = unstable_pole_agreement([direct, joint])
    assert agree.passed and agree.value < 0.02


def test_saturation_breaks_the_linear_stage_one_and_the_checks_say_so():
    # a saturating controller makes r -> u nonlinear: the two-stage plant is wrong, its residual is not white,
    # and it disagrees with the direct route, which does not care
    exp = _record(seed=1, saturation=0.5)
    two = TwoStageProjection(order=4, sensitivity_order=8, references=["r1", "r2"]).fit(exp)
    direct = DirectPredictionError(order=4, references=["r1", "r2"]).fit(exp)
    assert not two.passed
    assert not unstable_pole_agreement([direct, two]).passed
    np.testing.assert_allclose(np.sort(direct.unstable_poles.real), lp.UNSTABLE_POLES, rtol=0.02)


def test_references_are_required(linear_record):
    with pytest.raises(DataError, match="needs recorded references"):
        TwoStageProjection(order=4).fit(linear_record)
    with pytest.raises(DataError, match="needs recorded references"):
        JointInputOutput(order=8).fit(linear_record)


def test_route_results_hold_the_plant_as_model_with_read_only_diagnostics(linear_record):
    import pickle

    est = JointInputOutput(order=8, references=["r1", "r2"])
    res = est.fit(linear_record)
    est.order = 4  # a setting changed after the fit does not reach the result
    assert res.estimator is not est and res.estimator.get_params()["order"] == 8
    assert res.plant is res.model and res.details is res.diagnostics  # the former names read the same
    assert set(res.diagnostics) == {"reference_share", "weak_modes_left_out", "orders"}
    with pytest.raises(TypeError):
        res.diagnostics["reference_share"] = 1.0
    back = pickle.loads(pickle.dumps(res))
    assert np.array_equal(back.model.frequency_response(BAND), res.model.frequency_response(BAND))
    assert dict(back.diagnostics) == dict(res.diagnostics)
