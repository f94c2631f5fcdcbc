"""The residual tests' statistics, thresholds and degrees of freedom against hand computations
on short records: Ljung-Box over lags 1..M, the independence sum over lags 0..M."""

import numpy as np
import pytest
from scipy.stats import chi2, norm

from stageid.validation.residuals import independence_test, whiteness_test


def _ljung_box(records: list[np.ndarray], max_lag: int) -> float:
    """Q = N (N + 2) sum_k r(k)^2 / (N - k), r pooled over records, written out with loops."""
    centred = [x - x.mean() for x in records]
    n = sum(len(x) for x in centred)
    energy = sum(sum(v * v for v in x) for x in centred)
    q = 0.0
    for k in range(1, max_lag + 1):
        r = sum(sum(x[t + k] * x[t] for t in range(len(x) - k)) for x in centred) / energy
        q += r * r / (n - k)
    return n * (n + 2) * q


@pytest.mark.parametrize("alpha", [0.01, 0.05])
def test_whiteness_statistic_threshold_and_p_value_by_hand(alpha):
    rng = np.random.default_rng(0)
    e = rng.standard_normal(60) + 0.4 * np.sin(np.arange(60))  # some correlation: Q well above 0
    t = whiteness_test([e], max_lag=3, alpha=alpha)
    np.testing.assert_allclose(t.statistic, _ljung_box([e], 3), rtol=1e-12)
    assert t.dof == 3
    assert t.threshold == pytest.approx(chi2.ppf(1 - alpha, 3), rel=1e-12)
    assert t.p_value == pytest.approx(chi2.sf(t.statistic, 3), rel=1e-12)
    assert t.passed == (t.statistic <= chi2.ppf(1 - alpha, 3))
    assert t.bound == pytest.approx(norm.ppf(1 - alpha / 2) / np.sqrt(60), rel=1e-12)
    assert t.n_samples == 60 and list(t.lags) == [1, 2, 3]


def test_whiteness_pools_records_without_crossing_their_boundary():
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal(40), rng.standard_normal(30) + 1.0
    t = whiteness_test([a, b], max_lag=5)
    np.testing.assert_allclose(t.statistic, _ljung_box([a, b], 5), rtol=1e-12)
    assert t.n_samples == 70


def test_whiteness_decision_sits_on_the_threshold():
    # a residual whose Q lies between chi2(0.99, M) and chi2(0.995, M) must fail at alpha = 1 %
    rng = np.random.default_rng(2)
    lo, hi = chi2.ppf(0.99, 4), chi2.ppf(0.995, 4)
    for _ in range(4000):
        e = rng.standard_normal(80)
        q = _ljung_box([e], 4)
        if lo < q < hi:
            break
    else:
        pytest.fail("no record with Q between the two quantiles")
    assert not whiteness_test([e], max_lag=4, alpha=0.01).passed


def _prewhitened_sum(e: np.ndarray, u: np.ndarray, order: int, max_lag: int) -> float:
    """S = N sum_{k=0}^{M} r_ev(k)^2 with v = A(q) u, A the least-squares AR(order) fit, by hand."""
    uc = u - u.mean()
    rows = [[uc[t - i - 1] for i in range(order)] for t in range(order, len(uc))]
    a, *_ = np.linalg.lstsq(np.array(rows), uc[order:], rcond=None)
    v = np.array([uc[t] - sum(a[i] * uc[t - i - 1] for i in range(order)) for t in range(order, len(uc))])
    ev = e[order:] - e[order:].mean()
    v = v - v.mean()
    scale = np.sqrt(sum(x * x for x in ev) * sum(x * x for x in v))
    s = 0.0
    for k in range(max_lag + 1):
        r = sum(ev[t + k] * v[t] for t in range(len(v) - k)) / scale
        s += r * r
    return len(v) * s


@pytest.mark.parametrize("alpha", [0.01, 0.05])
def test_independence_statistic_threshold_and_dof_by_hand(alpha):
    rng = np.random.default_rng(3)
    u = np.convolve(rng.standard_normal(90), [1.0, 0.7, 0.3], "same")
    e = 0.3 * np.roll(u, 1) + rng.standard_normal(90)
    t = independence_test([e], [u], max_lag=4, alpha=alpha, n_prewhiten=2)
    np.testing.assert_allclose(t.statistic, _prewhitened_sum(e, u, 2, 4), rtol=1e-10)
    assert t.dof == 5  # lags 0..4
    assert list(t.lags) == [0, 1, 2, 3, 4]
    assert t.threshold == pytest.approx(chi2.ppf(1 - alpha, 5), rel=1e-12)
    assert t.p_value == pytest.approx(chi2.sf(t.statistic, 5), rel=1e-12)
    assert t.passed == (t.statistic <= chi2.ppf(1 - alpha, 5))
    assert t.bound == pytest.approx(norm.ppf(1 - alpha / 2) / np.sqrt(90), rel=1e-12)
