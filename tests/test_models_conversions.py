"""The one tf2ss and the one leading-zero trim (``models/conversions.py``) against scipy and numpy.

The closed-loop ZOH and the stage dynamics build their realisations here: the matrices must be
scipy's to the bit (so fits are unchanged), and the stage dynamics' model keeps its frequency
response and poles.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from stageid.hysteresis.stage.dynamics import transfer_to_statespace, zoh_resonance
from stageid.models.conversions import strip_leading_zeros, tf2ss_siso


def _random_pairs(n_cases: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for k in range(n_cases):
        nd = int(rng.integers(2, 7))
        nn = int(rng.integers(1, nd + 1))
        den = rng.standard_normal(nd) * 10 ** rng.uniform(-3, 6, nd)
        num = rng.standard_normal(nn) * 10 ** rng.uniform(-3, 6, nn)
        if k % 5 == 0 and nn > 1:
            num[0] = 0.0  # scipy trims it
        yield k, num, den


@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")  # the tiny-leading-coefficient cases
def test_tf2ss_siso_equals_scipy_to_the_bit():
    for _, num, den in _random_pairs(600):
        for x, y in zip(ss.tf2ss(num, den), tf2ss_siso(num, den), strict=True):
            assert x.shape == y.shape and np.array_equal(x, y)


def test_tf2ss_siso_edge_cases():
    # a static gain has no state (scipy gives it one at the origin); a zero numerator likewise
    A, B, C, D = tf2ss_siso(np.array([3.0]), np.array([0.0, 2.0]))
    assert A.shape == (0, 0) and D[0, 0] == 1.5
    A, B, C, D = tf2ss_siso(np.zeros(2), np.array([1.0, -0.5]))
    assert A.shape == (0, 0) and D[0, 0] == 0.0
    A, B, C, D = tf2ss_siso(np.zeros(2), np.array([1.0, -0.5]), keep_states=True)  # scipy's form
    assert A.tolist() == [[0.5]] and B.tolist() == [[1.0]] and C.tolist() == [[0.0]] and D[0, 0] == 0.0
    with pytest.raises(ValueError):  # improper: scipy's refusal, unchanged
        tf2ss_siso(np.array([1.0, 2.0, 3.0]), np.array([1.0, 0.5]))


def test_strip_leading_zeros_equals_trim_zeros():
    rng = np.random.default_rng(1)
    for k in range(200):
        x = np.concatenate([np.zeros(k % 4), rng.standard_normal(1 + k % 5)])
        assert np.array_equal(np.trim_zeros(x, "f"), strip_leading_zeros(x))
    assert np.array_equal(strip_leading_zeros(np.zeros(3)), np.zeros(1))


@pytest.mark.parametrize(
    "b, a",
    [
        ([0.5, 0.0], [1.0, -0.5]),
        ([0.0, 0.3, 0.2], [1.0, -0.9, 0.4]),  # b_0 = 0: a one-sample delay
        ([0.3, -0.2, 0.4, 0.1, 0.05], [1.0, -1.2, 0.6, -0.1, 0.02]),
        zoh_resonance(900.0, 0.05, 1e-4),
    ],
)
def test_stage_dynamics_keep_response_and_poles(b, a):
    # basis-invariant: the model from conversions answers like scipy's realisation of B(z)/A(z)
    b, a = np.asarray(b, dtype=float), np.asarray(a, dtype=float)
    g = transfer_to_statespace(b, a, 1e-4)
    z = np.exp(2j * np.pi * np.linspace(0.0, 0.5, 57))
    expected = np.polyval(b, z) / np.polyval(a, z)  # equal lengths: z^-1 and z coefficients agree
    got = np.array([(g.C @ np.linalg.solve(zk * np.eye(g.A.shape[0]) - g.A, g.B) + g.D)[0, 0] for zk in z])
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)  # a few roundings of O(1) numbers
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(g.A)), np.sort_complex(np.roots(a)), atol=1e-9)
