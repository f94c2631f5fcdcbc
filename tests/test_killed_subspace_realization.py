"""Tests that kill surviving mutants of ``subspace/realization.py`` (tests/MUTATION.md): the
Hankel sizes and order bounds of eq. 14 / Lemma 1 and the feed-through switch, on Markov
parameters of systems written down by hand.
"""

from __future__ import annotations

import numpy as np
import pytest

from stageid._errors import IdentificationError
from stageid.subspace.realisation.era import era, hankel_matrices, markov_realization
from stageid.subspace.realisation.route import RouteTask


def _markov(A, B, C, D, n: int) -> np.ndarray:
    A, B, C = np.atleast_2d(A), np.atleast_2d(B), np.atleast_2d(C)
    out = [np.atleast_2d(D)]
    Ak = np.eye(A.shape[0])
    for _ in range(1, n):
        out.append(C @ Ak @ B)
        Ak = A @ Ak
    return np.array(out)


A3 = np.array([[0.8, 0.3, 0.0], [-0.3, 0.8, 0.0], [0.0, 0.0, -0.5]])
B3 = np.array([[1.0], [0.0], [1.0]])
C3 = np.array([[1.0, 0.5, 2.0]])


def test_hankel_matrices_need_n1_plus_n2_plus_3_markov_parameters() -> None:
    Y = np.arange(6.0)[:, None, None]  # Y_k = k
    H0, H1 = hankel_matrices(Y, 1, 2)  # 1 + 2 + 3 = 6: exactly enough
    np.testing.assert_array_equal(H0, [[1, 2], [2, 3], [3, 4]])  # block (i, j) = Y_(1 + i + j)
    np.testing.assert_array_equal(H1, [[2, 3], [3, 4], [4, 5]])
    with pytest.raises(IdentificationError, match="needs 6 Markov parameters; got 5"):
        hankel_matrices(Y[:5], 1, 2)


@pytest.mark.parametrize("n1, n2", [(1, 2), (2, 1)])
def test_era_order_bound_is_min_of_both_hankel_sizes(n1: int, n2: int) -> None:
    # SISO: order <= min(n1 + 1, n2 + 1) = 2, reached exactly by a second-order system
    Y = _markov(A3[:2, :2], B3[:2], C3[:, :2], 0.0, 12)
    A, B, C, D, _ = era(Y, 2, n1=n1, n2=n2)
    np.testing.assert_allclose(_markov(A, B, C, D, 12), Y, atol=1e-12)  # basis-free: Markov parameters
    with pytest.raises(IdentificationError, match=r"min\(m \(n1\+1\), q \(n2\+1\)\) = 2; got 3"):
        era(Y, 3, n1=n1, n2=n2)


def test_era_default_hankel_is_the_largest_square_one() -> None:
    Y = _markov(A3, B3, C3, 0.25, 30)  # 30 parameters: n1 = n2 = (30 - 3) // 2 = 13
    A, B, C, D, s = era(Y, 3)
    assert s.size == 14  # every singular value of the 14 x 14 H(0)
    assert np.all(s[3:] < 1e-9 * s[0]) and s[2] > 1e-3 * s[0]  # rank 3
    np.testing.assert_allclose(_markov(A, B, C, D, 30), Y, atol=1e-10)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A)), np.sort_complex(np.linalg.eigvals(A3)), atol=1e-9)


def test_markov_route_keeps_the_feedthrough_only_when_asked() -> None:
    # p = 2, m = q = 1: theta = [Gamma Phi D_p], D_p's first column is (Y_0, Y_1); Gamma = Phi = 0
    theta = np.zeros((2, 6))
    theta[0, 4], theta[1, 4] = 0.7, 0.5  # D = 0.7, CB = 0.5, nothing after
    for feedthrough, d in ((True, 0.7), (False, 0.0)):
        A, B, C, D, cost = markov_realization(RouteTask(theta, 2, 1, 1, 1, np.zeros(0), 1e-3, feedthrough, False, 0))
        assert D.tolist() == [[d]] and np.isnan(cost)
        assert (C @ B).item() == pytest.approx(0.5) and A.item() == pytest.approx(0.0, abs=1e-15)
