"""The prior of eq. 17: ``vec(theta) ~ N(vec(theta_0), P_0 (x) Sigma)``, picked by ``method``.

``method`` of ``HankelMAP`` picks the prior by name from :data:`METHODS`: for ``"map"`` the
weak default (:func:`default_prior`: ``theta_0 = 0``, ``P_0^-1`` a small multiple of each
regressor's energy) or a given :class:`Prior` in the data's units (:func:`map_prior`); for
``"ls"`` the flat prior of batch least squares, with a tiny ridge where the normal equations
are singular (:func:`least_squares_prior`, :func:`singular_pivot`).  The priors act in the
fit's coordinates, every channel at unit RMS (:func:`regressor_scales`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._errors import DataError
from ..statistics.hankel_toeplitz import WindowStatistics, regressor_indices

__all__ = [
    "Prior",
    "default_prior",
    "map_prior",
    "least_squares_prior",
    "METHODS",
    "singular_pivot",
    "regressor_scales",
    "DEFAULT_PRIOR_STRENGTH",
    "LS_SINGULAR_PIVOT",
    "LS_RIDGE_STRENGTH",
]


#: Relative strength of the default prior ``P_0^-1 = strength diag(sum x x^T)`` (how it was
#: chosen: ``studies/hankel_map/RESULTS.md``).
DEFAULT_PRIOR_STRENGTH = 1e-5


#: ``method="ls"``: normal equations whose smallest relative Cholesky pivot is below this are
#: singular (noise-free or strictly band-limited records) ...
LS_SINGULAR_PIVOT = 1e-12


#: ... and get this ridge (relative to each regressor's energy) instead of the minimum-norm
#: solution, which explains the records' mean offsets by a spurious mode at z = 1 (why:
#: ``benchmarks/RESULTS-subspace.md``, "Notes on constants").
LS_RIDGE_STRENGTH = 1e-10


@dataclass(frozen=True, eq=False)
class Prior:
    """Matrix-normal prior of ``theta``: mean ``theta0`` and precision ``P_0^-1`` (eq. 17).

    Parameters
    ----------
    theta0 : ndarray of shape (p q, d) or None
        Prior mean (None: zeros, as in the paper).
    precision : ndarray of shape (d, d) or (d,)
        ``P_0^-1`` in units of the noise covariance (a vector means a diagonal matrix).
        Zero precision is a flat prior: the MAP estimate is then least squares.
    """

    theta0: np.ndarray | None
    precision: np.ndarray

    @classmethod
    def from_covariance(cls, theta0: np.ndarray | None, covariance: np.ndarray, noise_variance: float) -> Prior:
        """The prior from an absolute parameter covariance and the measurement-error variance.

        Eq. 17 weighs the prior covariance ``P_0`` against the measurement-error variance
        ``sigma``: with ``Cov(vec theta) = P_0' (x) Sigma`` and ``Sigma = sigma I`` the column
        covariance in noise units is ``P_0' = covariance / sigma``.

        Parameters
        ----------
        theta0 : ndarray of shape (p q, d) or None
        covariance : ndarray of shape (d, d) or (d,)
            Prior covariance of each row of ``theta`` (a vector: diagonal).
        noise_variance : float
            Variance ``sigma`` of the model error ``Delta(k)`` of eq. 9, > 0.

        Examples
        --------
        >>> Prior.from_covariance(None, [4.0, 4.0], 0.01).precision.tolist()
        [0.0025, 0.0025]
        """
        if not noise_variance > 0:
            raise DataError(f"`noise_variance` must be positive; got {noise_variance!r}.")
        cov = np.asarray(covariance, dtype=float)
        prec = noise_variance / cov if cov.ndim == 1 else noise_variance * np.linalg.inv(cov)
        return cls(None if theta0 is None else np.asarray(theta0, dtype=float), prec)

    def matrix(self, d: int) -> np.ndarray:
        """The precision as a (d, d) matrix."""
        prec = np.asarray(self.precision, dtype=float)
        if prec.ndim == 1:
            prec = np.diag(prec)
        if prec.shape != (d, d):
            raise DataError(f"prior precision must have shape ({d}, {d}) or ({d},); got {prec.shape}.")
        return prec

    def mean(self, rows: int, d: int) -> np.ndarray:
        """The prior mean as a (rows, d) matrix."""
        if self.theta0 is None:
            return np.zeros((rows, d))
        t0 = np.asarray(self.theta0, dtype=float)
        if t0.shape != (rows, d):
            raise DataError(f"prior mean `theta0` must have shape ({rows}, {d}); got {t0.shape}.")
        return t0


def default_prior(stats: WindowStatistics, strength: float = 1e-5) -> Prior:
    """The weak default prior: ``theta0 = 0`` and ``P_0^-1 = strength * diag(sum x x^T)``.

    Scaling by the regressors' own energy makes the prior independent of units; with
    ``strength`` = 1e-5 the prior mainly acts on directions the data hardly determine
    (out-of-band and band-edge directions of band-limited records), which keeps the normal
    equations well conditioned without moving the in-band predictions noticeably (see
    ``theta_frequency_response`` and the choice documented in ``HankelMAP``).
    """
    # the diagonal of sum x x^T straight from the window Gram matrix: no block copies
    diag = np.clip(
        np.diagonal(stats.W)[regressor_indices(stats.horizon, stats.n_inputs, stats.n_outputs)[0]], 0.0, None
    )
    floor = max(float(diag.max(initial=0.0)), 1e-300) * 1e-12
    return Prior(None, strength * np.maximum(diag, floor))


def regressor_scales(p: int, su: np.ndarray, sy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scales of ``x = [u past; y past; u future]`` and of ``y_p`` (eq. 9 order: time-major)
    for channels scaled by ``su`` (inputs) and ``sy`` (outputs)."""
    return np.concatenate([np.tile(su, p), np.tile(sy, p), np.tile(su, p)]), np.tile(sy, p)


def singular_pivot(stats: WindowStatistics) -> float | None:
    """The smallest relative Cholesky pivot of ``sum x x^T`` (unit diagonal) when it is below
    ``LS_SINGULAR_PIVOT`` (0.0 when the factorisation fails), else None."""
    XX = stats.blocks()[0]
    dg = np.sqrt(np.clip(np.diag(XX), 0.0, None))
    dg = np.where(dg > 0, dg, 1.0)
    try:
        L = np.linalg.cholesky(XX / np.outer(dg, dg))
    except np.linalg.LinAlgError:
        return 0.0
    pivot = float(np.min(np.diag(L)) ** 2)
    return pivot if pivot < LS_SINGULAR_PIVOT else None


def map_prior(stats: WindowStatistics, prior: None | float | Prior, su: np.ndarray, sy: np.ndarray) -> Prior:
    """``method="map"``: the prior of eq. 17 in the fit's coordinates (channels divided by ``su``, ``sy``).

    None: :func:`default_prior` of strength ``DEFAULT_PRIOR_STRENGTH``; a float: that
    strength; a :class:`Prior` is taken in the data's units and scaled
    (``theta_s = theta diag(xs) / ys``, ``P0s^-1 = P0^-1 / (xs xs^T)``).
    """
    if isinstance(prior, Prior):
        xs, ys = regressor_scales(stats.horizon, su, sy)
        prec = np.asarray(prior.precision, dtype=float)
        if prec.shape == xs.shape:
            prec = prec / xs**2
        elif prec.shape == (xs.size, xs.size):
            prec = prec / np.outer(xs, xs)  # other shapes: map_estimate reports them
        t0 = None if prior.theta0 is None else np.asarray(prior.theta0, dtype=float)
        if t0 is not None and t0.shape == (ys.size, xs.size):
            t0 = t0 * xs[None, :] / ys[:, None]
        return Prior(t0, prec)
    strength = DEFAULT_PRIOR_STRENGTH if prior is None else float(prior)
    return default_prior(stats, strength)


def least_squares_prior(
    stats: WindowStatistics, prior: None | float | Prior, su: np.ndarray, sy: np.ndarray
) -> Prior | None:
    """``method="ls"``: the flat prior (None, batch least squares), or the ridge
    ``LS_RIDGE_STRENGTH`` on singular normal equations (``prior`` is not used)."""
    return default_prior(stats, LS_RIDGE_STRENGTH) if singular_pivot(stats) is not None else None


#: ``method`` of ``HankelMAP`` -> the function giving the prior of eq. 17.
METHODS = {"map": map_prior, "ls": least_squares_prior}
