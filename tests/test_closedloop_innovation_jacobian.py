"""The analytic Jacobian of the innovation predictor's errors against central differences of the same cost."""

import numpy as np
import pytest

from stageid.closedloop.innovation_jacobian import error_sensitivity, n_parameters
from stageid.closedloop.innovation_pem import pack, stacked_residuals, transient_length, unpack, weighted_jacobian
from stageid.closedloop.predictor_subspace import InnovationMatrices, pbsid
from stageid.plants import levitated_pair as lp


def _problem(feedthrough, seed=0, n_samples=2500):
    """A PBSID start of the 2x2 levitated pair, offsets made non-zero, and the cost's pieces."""
    rng = np.random.default_rng(seed)
    _, u, y = lp.record(n_samples, seed=seed, noise=0.02)
    records = [((u - u.mean(0)) / u.std(0), (y - y.mean(0)) / y.std(0))]
    s = pbsid(records, 4, 10, feedthrough)
    start = InnovationMatrices(
        s.A, s.B, s.C, s.D, s.K, s.noise_cov, 0.01 * rng.standard_normal(4), 0.01 * rng.standard_normal(2)
    )
    stacked = [np.hstack([u_, np.ones((u_.shape[0], 1)), y_]) for u_, y_ in records]
    W = np.linalg.inv(np.linalg.cholesky(s.noise_cov))
    return start, stacked, W


def _central_differences(start, stacked, W, burn, feedthrough):
    def cost(theta):
        mats = unpack(theta, 4, 2, 2, feedthrough, start.noise_cov)
        return np.concatenate([(e[burn:] @ W.T).ravel() for e in stacked_residuals(mats, stacked)])

    theta = pack(start, feedthrough)
    J = np.empty((cost(theta).size, theta.size))
    for k in range(theta.size):
        h = 1e-6 * max(abs(theta[k]), 1e-2)
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        J[:, k] = (cost(up) - cost(down)) / (2 * h)
    return J


@pytest.mark.parametrize("feedthrough", [False, True], ids=["strictly-proper", "feedthrough"])
@pytest.mark.parametrize("burn", [1, 80], ids=["initial-state-in-cost", "transient-left-out"])
def test_the_sensitivity_jacobian_matches_central_differences(feedthrough, burn):
    start, stacked, W = _problem(feedthrough)
    # burn 1 keeps the rows where the fitted initial state acts, so its variable-projection term is checked
    assert (transient_length(start, 1, 2500) > burn) is (burn == 1)
    J = weighted_jacobian(start, stacked, W, burn, feedthrough)
    J_fd = _central_differences(start, stacked, W, burn, feedthrough)
    assert J.shape == J_fd.shape == ((2500 - burn) * 2, n_parameters(4, 2, 2, feedthrough))
    # central differences with steps of 1e-6 relative agree to about 1e-8 of a column's size;
    # 1e-4 leaves room for rounding in the offsets' columns and nothing for a wrong term
    scale = np.abs(J_fd).max(axis=0)
    assert np.all(np.abs(J - J_fd).max(axis=0) <= 1e-4 * scale)


def test_a_defective_predictor_is_left_to_finite_differences():
    # A - K C a Jordan block: no eigenvector basis, so the modal filters are not used
    A = np.array([[0.5, 1.0], [0.0, 0.5]])
    mats = InnovationMatrices(A, np.ones((2, 1)), np.array([[1.0, 0.0]]), np.zeros((1, 1)), np.zeros((2, 1)), np.eye(1))
    z = np.random.default_rng(0).standard_normal((50, 3))
    assert error_sensitivity(mats, z, False) is None
