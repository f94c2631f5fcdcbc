"""MAP online estimation of the Hankel-Toeplitz parameters, Cao & Chen (2013) section 2.3.

The parameter matrix ``theta = [Gamma Phi D_p]`` of eq. 16 gets a matrix-normal prior
``vec(theta) ~ N(vec(theta_0), P_0 (x) Sigma)`` where ``Sigma`` is the covariance of the
model error ``Delta(k)`` (the paper's "variance matrix of measurement errors" sigma).
With this conjugate prior the posterior after the windows ``x_1 .. x_i`` is again
matrix-normal with mean ``theta_i`` and column covariance ``P_i``, and eq. 17-18 read

    E_{i+1}     = y_p(i+1) - theta_i x_{i+1}                                   (eq. 18)
    g_{i+1}     = P_i x_{i+1} / (lambda + x_{i+1}^T P_i x_{i+1})
    theta_{i+1} = theta_i + E_{i+1} g_{i+1}^T          (= theta_i + E P_{i+1} x sigma^-1, eq. 17)
    P_{i+1}     = (P_i - g_{i+1} x_{i+1}^T P_i) / lambda

(``lambda`` = 1: no forgetting; ``P`` is measured in units of ``Sigma`` so the mean update
does not depend on ``Sigma``; :meth:`Prior.from_covariance` converts an absolute prior
covariance and a measurement-error variance into these units).
The OCR of eq. 17 writes ``P X^T sigma^-1 E`` for a row-vector ``X``; with our column
vectors the consistent reading is the update above.

After all windows the recursion equals the batch formula (the information form)

    P_N^-1      = lambda^N P_0^-1 + sum_k lambda^(N-k) x_k x_k^T
    theta_N     = (lambda^N theta_0 P_0^-1 + sum_k lambda^(N-k) y_k x_k^T) P_N

which :func:`batch_posterior` evaluates from :class:`WindowStatistics` (lag correlations),
so fitting long records never runs the per-sample loop; :func:`map_posterior` is the step
``HankelMAP`` takes (a first fit, or an update continuing a posterior).  The sample-by-sample
recursion for streaming use is :func:`~stageid.subspace.map.recursion.recursive_map`.

``method`` of ``HankelMAP`` picks the prior by name from ``METHODS`` (:mod:`.prior`: the
weak default or a given :class:`Prior` for ``"map"``, the flat prior of batch least squares
for ``"ls"``); they are re-exported here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._errors import DataError, IdentificationError
from ..statistics.hankel_toeplitz import WindowStatistics
from .prior import (  # noqa: F401 - the prior's names, re-exported (PRIOR_NAMES)
    DEFAULT_PRIOR_STRENGTH,
    LS_RIDGE_STRENGTH,
    LS_SINGULAR_PIVOT,
    METHODS,
    Prior,
    default_prior,
    least_squares_prior,
    map_prior,
    regressor_scales,
    singular_pivot,
)
from .prior import __all__ as PRIOR_NAMES

# the prior's names are re-exported here (the old ``map_estimator`` module held both)
__all__ = ["Posterior", "map_estimate", "batch_posterior", "map_posterior", "prior_identity_diagonal", *PRIOR_NAMES]


@dataclass(frozen=True, eq=False)
class Posterior:
    """Matrix-normal posterior of ``theta`` in information form (exactly updatable).

    Attributes
    ----------
    information : ndarray of shape (d, d)
        ``P^-1`` (prior precision plus weighted ``sum x x^T``).
    moment : ndarray of shape (p q, d)
        ``theta0 P_0^-1 + sum y x^T`` (weighted), so ``theta = moment P``.
    theta : ndarray of shape (p q, d)
        Posterior mean (the MAP estimate).
    noise_cov : ndarray of shape (p q, p q)
        Estimated covariance ``Sigma`` of ``Delta(k)`` from the residuals.
    n_windows : float
        Weighted number of windows seen.
    horizon, n_inputs, n_outputs : int
    """

    information: np.ndarray
    moment: np.ndarray
    theta: np.ndarray
    noise_cov: np.ndarray
    n_windows: float
    horizon: int
    n_inputs: int
    n_outputs: int
    residual: np.ndarray  # weighted residual sum of squares matrix (p q, p q)
    data_sums: tuple[np.ndarray, np.ndarray, np.ndarray] = ()  # weighted (XX, YX, YY) of the data alone

    @property
    def covariance(self) -> np.ndarray:
        """Column covariance ``P`` of shape (d, d): ``Cov(vec theta) = P (x) Sigma``."""
        return _inverse_psd(self.information)

    def theta_std(self) -> np.ndarray:
        """Posterior standard deviation of each entry of ``theta``, shape (p q, d)."""
        return np.sqrt(np.outer(np.clip(np.diag(self.noise_cov), 0, None), np.clip(np.diag(self.covariance), 0, None)))

    def updated(self, stats: WindowStatistics, forgetting: float = 1.0) -> Posterior:
        """The posterior after more windows (old information discounted by ``forgetting^n``)."""
        if (stats.horizon, stats.n_inputs, stats.n_outputs) != (self.horizon, self.n_inputs, self.n_outputs):
            raise DataError(
                f"new data must have horizon {self.horizon}, {self.n_inputs} inputs and {self.n_outputs} outputs; "
                f"got {stats.horizon}, {stats.n_inputs} and {stats.n_outputs}."
            )
        XX, YX, YY = stats.blocks()
        discount = forgetting**stats.count
        info = discount * self.information + XX
        moment = discount * self.moment + YX
        theta = _solve(info, moment)
        sums = tuple(discount * a + b for a, b in zip(self.data_sums, (XX, YX, YY)))
        residual = _residual(theta, *sums)
        n = discount * self.n_windows + stats.n_windows
        d = info.shape[0]
        noise = residual / max(n - d, 1.0)
        return Posterior(info, moment, theta, noise, n, self.horizon, self.n_inputs, self.n_outputs, residual, sums)


def _inverse_psd(M: np.ndarray) -> np.ndarray:
    try:
        c = np.linalg.cholesky(M)
        ci = np.linalg.solve(c, np.eye(M.shape[0]))
        return ci.T @ ci
    except np.linalg.LinAlgError:
        return np.linalg.pinv(M, hermitian=True)


def _solve(info: np.ndarray, moment: np.ndarray, definite: bool = False) -> np.ndarray:
    """``moment @ info^-1`` for a symmetric positive (semi)definite ``info``.

    A singular or indefinite-by-rounding ``info`` (flat prior on data that are not
    persistently exciting) gives the minimum-norm least-squares solution; a Cholesky
    factorisation decides which, unless the caller knows ``info`` is definite (a prior
    with positive precision).  The solve itself is numpy's LU rather than scipy.linalg's
    Cholesky solve: about 1.5x the flops, but importing scipy.linalg costs several
    times the whole solve in a command-line run.
    """
    try:
        if not definite:
            np.linalg.cholesky(info)
        return np.linalg.solve(info, moment.T).T
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(info, moment.T, rcond=None)[0].T


def _residual(
    theta: np.ndarray, XX: np.ndarray, YX: np.ndarray, YY: np.ndarray, prior_diag: np.ndarray | None = None
) -> np.ndarray:
    """``sum (y - theta x)(y - theta x)^T`` from the sums; with ``prior_diag``, the diagonal
    precision of a prior around zero under which ``theta (XX + diag) = YX``, by the identity
    ``theta XX theta^T = YX theta^T - theta diag theta^T`` (no ``(d x d)`` product: about 0.4x the
    flops).  Priors of material strength only (see :func:`prior_identity_diagonal`)."""
    if prior_diag is not None:
        R = YY - theta @ (YX + theta * prior_diag[None, :]).T
        return 0.5 * (R + R.T)
    T = theta @ YX.T
    return YY - T - T.T + theta @ XX @ theta.T


def prior_identity_diagonal(prior: Prior | None, XX: np.ndarray) -> np.ndarray | None:
    """The diagonal precision of ``prior`` when the residual may use the MAP identity of
    :func:`_residual`: a prior around zero of at least 1e-8 of each regressor's energy, where the
    identity keeps the small residual (1 % noise: ~1e-4 of the output energy) to ~1e-7; else None."""
    if prior is None or prior.theta0 is not None or np.ndim(prior.precision) != 1:
        return None
    diag = np.asarray(prior.precision, dtype=float)
    if diag.shape == (XX.shape[0],) and np.all(diag >= 1e-8 * np.abs(XX.diagonal())):
        return diag
    return None


def map_estimate(XX: np.ndarray, YX: np.ndarray, prior: Prior | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Posterior mean of eq. 16 from ``sum x x^T`` and ``sum y x^T``, without the residual.

    Returns ``(theta, information, moment)`` with ``information = XX + P_0^-1`` and
    ``moment = YX + theta_0 P_0^-1`` (``XX``, ``YX`` themselves for the flat prior ``None``).

    Parameters
    ----------
    XX : ndarray of shape (d, d)
    YX : ndarray of shape (p q, d)
    prior : Prior or None

    Raises
    ------
    DataError
        When the prior's shapes do not match ``d``.

    Examples
    --------
    >>> import numpy as np
    >>> theta, info, moment = map_estimate(np.eye(2), np.array([[1.0, 2.0]]), Prior(None, np.ones(2)))
    >>> theta.tolist()
    [[0.5, 1.0]]
    """
    d = XX.shape[0]
    definite = False
    if prior is None:
        info = XX.copy()
        moment = YX.copy()
    elif prior.theta0 is None and np.ndim(prior.precision) == 1:
        # diagonal prior around zero (the default): no (d x d) products with the precision
        diag = np.asarray(prior.precision, dtype=float)
        if diag.shape != (d,):
            raise DataError(f"prior precision must have shape ({d}, {d}) or ({d},); got {diag.shape}.")
        info = XX.copy()
        info[np.diag_indices(d)] += diag
        moment = YX.copy()
        definite = bool(np.all(diag > 0))
    else:
        prec = prior.matrix(d)
        info = XX + prec
        moment = YX + prior.mean(YX.shape[0], d) @ prec
    return _solve(info, moment, definite), info, moment


def batch_posterior(stats: WindowStatistics, prior: Prior | None) -> Posterior:
    """MAP estimate of eq. 16 from the normal-equation statistics (equals the recursion's end).

    Parameters
    ----------
    stats : WindowStatistics
        From :func:`~stageid.subspace.statistics.hankel_toeplitz.window_statistics` (summed over records).
    prior : Prior or None
        None is the flat prior: batch least squares, the identified-Hankel-matrix method of
        Lim, Phan & Longman that the paper compares against (minimum-norm solution when the
        normal equations are singular).

    Returns
    -------
    Posterior

    Raises
    ------
    IdentificationError
        When the estimate is not finite.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.subspace.statistics.hankel_toeplitz import window_statistics
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((400, 1)); y = np.convolve(u[:, 0], [0, 0.5, 0.25])[:400, None]
    >>> post = batch_posterior(window_statistics(u, y, 2), None)
    >>> post.theta.shape
    (2, 6)
    """
    XX, YX, YY = stats.blocks()
    d = XX.shape[0]
    theta, info, moment = map_estimate(XX, YX, prior)
    if not np.all(np.isfinite(theta)):
        raise IdentificationError(
            "the Hankel-Toeplitz estimate is not finite; the data are not informative enough for this horizon."
        )
    residual = _residual(theta, XX, YX, YY, prior_identity_diagonal(prior, XX))
    noise = residual / max(stats.n_windows - d, 1.0)
    return Posterior(
        info,
        moment,
        theta,
        noise,
        stats.n_windows,
        stats.horizon,
        stats.n_inputs,
        stats.n_outputs,
        residual,
        (XX, YX, YY),
    )


def map_posterior(
    stats: WindowStatistics, prior: Prior | None, previous: Posterior | None = None, forgetting: float = 1.0
) -> Posterior:
    """Eq. 16-18: the posterior of ``theta = [Gamma Phi D_p]`` after the windows of ``stats``.

    The end of the recursion of eq. 17-18 (``theta_(i+1) = theta_i + P_(i+1) X sigma^-1 E``,
    ``E = y_p - theta_i X``) over all windows, in information form.  A first fit starts from
    ``prior`` (:func:`batch_posterior`); an update continues ``previous``, whose information
    is discounted by ``forgetting`` to the power of the new window count (``prior`` is then
    not used: it is already in ``previous``).
    """
    if previous is not None:
        return previous.updated(stats, forgetting)
    return batch_posterior(stats, prior)
