"""Tests written to kill survivors of the ``validation`` mutation group (tests/MUTATION.md)."""

import numpy as np
import pytest

from stageid import DataError
from stageid.validation.metrics import fit_percent, nrmse, relative_response_error, rms_error


def test_relative_response_error_per_column_and_per_entry_by_hand():
    true = np.zeros((3, 2, 2), complex)
    true[:, 0, 0] = [1.0, 4.0, 2.0]  # column 0 peaks at 4 (entry 0,0)
    true[:, 1, 0] = [0.5, 0.5, 0.5]
    true[:, 0, 1] = [1j, 1j, 1j]
    true[:, 1, 1] = [10.0, 1.0, 1.0]  # column 1 peaks at 10 (entry 1,1)
    est = true.copy()
    est[1, 0, 0] += 0.4  # 0.4 off
    est[2, 1, 0] += 0.1j  # 0.1 off
    est[0, 0, 1] += 0.5  # 0.5 off
    est[2, 1, 1] -= 2.0  # 2 off
    err = np.array([[0.4, 0.5], [0.1, 2.0]])
    np.testing.assert_allclose(relative_response_error(est, true), err / np.array([[4.0, 10.0]]), rtol=1e-12)
    np.testing.assert_allclose(
        relative_response_error(est, true, per="entry"), err / np.array([[4.0, 1.0], [0.5, 10.0]]), rtol=1e-12
    )
    with pytest.raises(DataError, match="must both have shape"):
        relative_response_error(est[:, :, :1], true)
    with pytest.raises(DataError, match="must both have shape"):
        relative_response_error(est[:, 0, 0], true[:, 0, 0])
    with pytest.raises(DataError, match="`per`"):
        relative_response_error(est, true, per="row")


def test_fit_nrmse_and_rms_by_hand():
    y = np.array([[0.0, 1.0], [2.0, 1.0], [4.0, 1.0], [2.0, 1.0]])
    yh = y + np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 0.0], [-1.0, 0.0]])
    # column 0: mean 2, ||y - mean|| = sqrt(8), ||e|| = 2; column 1 is constant
    np.testing.assert_allclose(fit_percent(y, yh), [100.0 * (1.0 - 2.0 / np.sqrt(8.0)), np.nan], rtol=1e-12)
    np.testing.assert_allclose(rms_error(y, yh), [1.0, 0.0], rtol=1e-12)
    np.testing.assert_allclose(nrmse(y[:, :1], yh[:, :1]), [1.0 / 4.0], rtol=1e-12)


@pytest.mark.parametrize("alpha", [-0.5, 0.0, 1.0, 1.5, float("nan")])
def test_a_test_level_outside_zero_one_is_refused(alpha):
    from stageid.validation.residuals import independence_test, whiteness_test

    e = np.random.default_rng(0).standard_normal(200)
    with pytest.raises(DataError, match="`alpha` must lie in"):
        whiteness_test([e], max_lag=5, alpha=alpha)
    with pytest.raises(DataError, match="`alpha` must lie in"):
        independence_test([e], [np.cumsum(e)], max_lag=5, alpha=alpha)
