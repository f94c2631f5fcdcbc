"""The correlation tests of a residual (MATLAB ``resid``): is it white, and independent of an input?

The residual is the simulation error ``e = y - y_model`` of each output.  Two tests, each one
chi-square test at the ``alpha`` level (default 1 %) over a band of lags, so that a correct
model passes ``1 - alpha`` of the time (per-lag bounds over 25 lags would each be crossed by
chance and fail a correct model most of the time):

whiteness
    The Ljung-Box portmanteau statistic over lags ``1..M`` of the residual's autocorrelation
    ``r_ee(k)``::

        Q = N (N + 2) sum_{k=1}^{M} r_ee(k)^2 / (N - k)    ~  chi2(M)   when e is white.

independence (per input)
    The cross-correlation ``r_ev(k)``, ``k = 0..M``, between the residual and the *prewhitened*
    input ``v = A(q) u`` (``A`` a least-squares AR(``n_prewhiten``) fit to ``u``)::

        S = N sum_{k=0}^{M} r_ev(k)^2    ~  chi2(M + 1)   when e is white and independent of u.

    With ``v`` white and ``e`` white the lags are asymptotically uncorrelated with variance
    ``1/N``, so S is chi-square for a coloured (chirp, low-pass) excitation; without the
    prewhitening the lags of a smooth input are strongly correlated and ``N sum r^2`` is far
    from chi2 (Ljung, *System Identification*, 2nd ed., sec. 16.6).  A coloured residual makes
    the lags correlated again; the whiteness test flags that case.

Per-lag correlations (of the raw residual and raw input, as ``resid`` draws them) are returned
with the per-lag bound ``z_{1-alpha/2} / sqrt(N)`` for plotting.  Several records are pooled:
the lagged products are summed over records (no lag crosses a record boundary).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .._errors import DataError
from ..display import html_repr, short_repr

__all__ = [
    "MAX_LAG",
    "ALPHA",
    "CorrelationTest",
    "whiteness_test",
    "independence_test",
    "min_samples",
    "check_test_settings",
    "as_records",
]


MAX_LAG = 25  # default lags: 1..25 (whiteness) and 0..25 (independence)


ALPHA = 0.01  # default level of each test: 1 %


@dataclass(frozen=True)
class CorrelationTest:
    """The outcome of one chi-square test over lags.

    Attributes
    ----------
    passed : bool
        ``statistic <= threshold``.
    statistic, threshold, p_value : float
        The chi-square statistic, its ``1 - alpha`` quantile with ``dof`` degrees of freedom,
        and the probability of a larger value under the null hypothesis.
    dof : int
        Degrees of freedom (the number of lags tested).
    lags : ndarray of int
        The lags tested.
    correlations : ndarray of float
        Normalised correlations at ``lags`` (raw signals, for plotting).
    bound : float
        Per-lag ``1 - alpha`` bound ``z / sqrt(N)`` for plotting.
    max_abs : float
        ``max |correlations|``.
    n_samples : int
        Samples pooled over records.
    """

    passed: bool
    statistic: float
    threshold: float
    p_value: float
    dof: int
    lags: np.ndarray = field(repr=False)
    correlations: np.ndarray = field(repr=False)
    bound: float
    max_abs: float
    n_samples: int

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    @classmethod
    def chi_square(
        cls, statistic: float, dof: int, alpha: float, lags: np.ndarray, correlations: np.ndarray, n: int
    ) -> CorrelationTest:
        """The test of ``statistic`` against chi2(``dof``) at level ``alpha``; the per-lag bound from ``n``."""
        from scipy.stats import chi2, norm

        threshold = float(chi2.ppf(1 - alpha, dof))
        return cls(
            passed=statistic <= threshold,
            statistic=statistic,
            threshold=threshold,
            p_value=float(chi2.sf(statistic, dof)),
            dof=dof,
            lags=lags,
            correlations=correlations,
            bound=float(norm.ppf(1 - alpha / 2) / np.sqrt(n)),
            max_abs=float(np.max(np.abs(correlations))),
            n_samples=n,
        )

    def to_dict(self) -> dict:
        """JSON-ready dict: ``pass``, ``max_abs``, ``bound``, ``lags``, ``correlations``, ``statistic``..."""
        return {
            "pass": bool(self.passed),
            "max_abs": float(self.max_abs),
            "bound": float(self.bound),
            "lags": [int(k) for k in self.lags],
            "correlations": [float(c) for c in self.correlations],
            "statistic": float(self.statistic),
            "threshold": float(self.threshold),
            "p_value": float(self.p_value),
            "dof": int(self.dof),
            "n_samples": int(self.n_samples),
        }


def min_samples(max_lag: int) -> int:
    """Fewest samples (pooled) the tests accept for ``max_lag``: ``4 * (max_lag + 1)``, at least 50.

    Below that the chi-square approximation of a statistic over ``max_lag`` lags is meaningless.
    """
    return max(50, 4 * (max_lag + 1))


def as_records(signals: Sequence[np.ndarray]) -> list[np.ndarray]:
    """One flat float array per record; DataError for none."""
    out = [np.asarray(s, dtype=float).reshape(-1) for s in signals]
    if not out:
        raise DataError("residual tests need at least one record; got none.")
    return out


def check_test_settings(n: int, max_lag: int, alpha: float) -> None:
    """DataError unless ``max_lag`` is a positive integer, ``0 < alpha < 1`` and ``n >= min_samples(max_lag)``."""
    if not (isinstance(max_lag, (int, np.integer)) and max_lag >= 1):
        raise DataError(f"`max_lag` must be a positive integer; got {max_lag!r}.")
    if not (0 < alpha < 1):
        raise DataError(f"`alpha` must lie in (0, 1); got {alpha!r}.")
    if n < min_samples(max_lag):
        raise DataError(f"residual tests over {max_lag} lags need at least {min_samples(max_lag)} samples; got {n}.")


def _xcorr(a: list[np.ndarray], b: list[np.ndarray], lags: np.ndarray) -> tuple[np.ndarray, int]:
    """Pooled normalised correlation ``sum_t a(t + k) b(t) / sqrt(sum a^2 sum b^2)`` at ``lags`` (>= 0)."""
    a = [x - x.mean() for x in a]
    b = [x - x.mean() for x in b]
    n = sum(x.size for x in a)
    scale = np.sqrt(sum(float(x @ x) for x in a) * sum(float(x @ x) for x in b))
    if scale <= 0:
        raise DataError("residual tests need signals that vary; got a constant residual or input.")
    r = np.array([sum(float(x[k:] @ y[: y.size - k]) for x, y in zip(a, b)) for k in lags])
    return r / scale, n


def whiteness_test(residuals: Sequence[np.ndarray], max_lag: int = MAX_LAG, alpha: float = ALPHA) -> CorrelationTest:
    """Ljung-Box test that the residual is white over lags ``1..max_lag`` (module docstring).

    Parameters
    ----------
    residuals : sequence of array_like of shape (n_samples,)
        One residual per record (pooled).
    max_lag : int
    alpha : float
        Test level; a white residual fails with probability ``alpha``.

    Returns
    -------
    CorrelationTest
        The Ljung-Box ``Q`` against chi2(``max_lag``), the autocorrelations at lags ``1..max_lag``.

    Raises
    ------
    DataError
        Fewer than :func:`min_samples` samples, or a constant residual.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.validation.correlation_tests import whiteness_test
    >>> e = np.random.default_rng(0).standard_normal(2000)
    >>> whiteness_test([e]).passed
    True
    >>> whiteness_test([np.convolve(e, np.ones(5), "same")]).passed
    False
    """
    es = as_records(residuals)
    lags = np.arange(1, max_lag + 1)
    check_test_settings(sum(e.size for e in es), max_lag, alpha)
    r, n = _xcorr(es, es, lags)
    q = float(n * (n + 2) * np.sum(r**2 / (n - lags)))
    return CorrelationTest.chi_square(q, int(max_lag), alpha, lags, r, n)


def _ar_filter(u: list[np.ndarray], order: int) -> np.ndarray:
    """Least-squares AR(order) polynomial ``[1, a1, ..., a_order]`` of the pooled records ``u``."""
    rows, rhs = [], []
    for x in u:
        x = x - x.mean()
        if x.size <= order:
            continue
        rows.append(np.column_stack([x[order - i - 1 : x.size - i - 1] for i in range(order)]))
        rhs.append(x[order:])
    phi, target = np.vstack(rows), np.concatenate(rhs)
    a, *_ = np.linalg.lstsq(phi, target, rcond=None)
    return np.concatenate([[1.0], -a])


def _prewhiten(signals: list[np.ndarray], poly: np.ndarray) -> list[np.ndarray]:
    """``A(q) x`` per record, the first ``len(poly) - 1`` samples (filter start-up) dropped."""
    from scipy.signal import lfilter

    k = poly.size - 1
    return [lfilter(poly, [1.0], x - x.mean())[k:] for x in signals]


def independence_test(
    residuals: Sequence[np.ndarray],
    inputs: Sequence[np.ndarray],
    max_lag: int = MAX_LAG,
    alpha: float = ALPHA,
    n_prewhiten: int = 10,
) -> CorrelationTest:
    """Chi-square test that the residual is uncorrelated with one input over lags ``0..max_lag``.

    ``S = N sum_k r_ev(k)^2 ~ chi2(max_lag + 1)`` with ``v`` the input prewhitened by an
    AR(``n_prewhiten``) fit (module docstring).  ``correlations`` are those of the raw
    residual with the raw input (``r_eu(k)``, as ``resid`` plots them).

    Parameters
    ----------
    residuals, inputs : sequence of array_like of shape (n_samples,)
        One residual and one input per record, of equal lengths.
    max_lag : int
    alpha : float
    n_prewhiten : int
        Order of the AR prewhitening filter of the input.

    Returns
    -------
    CorrelationTest
        ``S`` against chi2(``max_lag + 1``), the raw cross-correlations at lags ``0..max_lag``.

    Raises
    ------
    DataError
        Unequal lengths, too few samples (pooled, or in one record), a constant input or residual.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.validation.correlation_tests import independence_test
    >>> rng = np.random.default_rng(1)
    >>> u = np.convolve(rng.standard_normal(3000), np.ones(8), "same")
    >>> independence_test([rng.standard_normal(3000)], [u]).passed
    True
    >>> independence_test([np.roll(u, 3) + rng.standard_normal(3000)], [u]).passed
    False
    """
    es, us = as_records(residuals), as_records(inputs)
    if len(es) != len(us) or any(e.size != u.size for e, u in zip(es, us)):
        raise DataError("residuals and inputs must be given per record with equal lengths.")
    lags = np.arange(0, max_lag + 1)
    check_test_settings(sum(e.size for e in es), max_lag, alpha)
    shortest = min(u.size for u in us)
    if shortest <= n_prewhiten + max_lag + 1:
        raise DataError(
            f"the independence test needs records of more than {n_prewhiten + max_lag + 1} samples "
            f"(AR({n_prewhiten}) prewhitening and {max_lag} lags); got one of {shortest}."
        )
    r_raw, n = _xcorr(es, us, lags)
    poly = _ar_filter(us, n_prewhiten)
    k = poly.size - 1
    r_white, n_white = _xcorr([e[k:] for e in es], _prewhiten(us, poly), lags)
    s = float(n_white * np.sum(r_white**2))
    return CorrelationTest.chi_square(s, max_lag + 1, alpha, lags, r_raw, n)
