"""Transient removal for periodic records by the local polynomial method (the BLA's robust LPM variant).

Pintelon, Barbe, Vandersteen & Schoukens, "Improved (non-)parametric identification of dynamic
systems excited by periodic signals", Mech. Syst. Signal Process. 25 (2011), sec. 3: in the DFT
of a whole record of ``P >= 2`` periods, the excitation and its nonlinear distortions live on
the lines ``k P``; the lines in between hold only the transient (a smooth function of
frequency) and the noise.  A polynomial of degree ``R`` in the line offset, fitted to the
in-between lines around ``k P``, gives the transient at ``k P`` (its intercept) and the noise
variance (its residual), so no period has to be dropped and a record that never reaches the
steady state still gives an unbiased FRF.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["transient_free_lines", "MIN_RESIDUAL_DOF"]

#: Residual degrees of freedom of each local fit (in-between lines beyond the polynomial's).
MIN_RESIDUAL_DOF = 6


def transient_free_lines(
    X: np.ndarray, harmonics: np.ndarray, periods: int, degree: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """The record's DFT at the lines ``harmonics * periods`` with the transient removed, and its noise variance.

    Parameters
    ----------
    X : ndarray of shape (n_bins, ...), complex
        DFT of the whole record (``rfft``), any trailing channel axes.
    harmonics : ndarray of int
        Lines on the grid of one period.
    periods : int
        Periods in the record (at least 2: the in-between lines are the transient's).
    degree : int
        Degree ``R`` of the local polynomial.  3 by default: on a symmetric window the
        intercept is the same as degree 2's, and the cubic term keeps the curvature of a lightly
        damped resonance's transient out of the noise estimate (degree 2 put the detection
        lines of a linear plant 5 dB below their noise; degree 3 within 0.6 dB).

    Returns
    -------
    Xc : ndarray of shape (n_harmonics, ...)
        ``X(k P) - T(k P)``.
    var : ndarray of shape (n_harmonics, ...)
        Variance of ``Xc`` from the noise: the residual variance of the local fit times
        ``1 + ||w||^2`` (``w`` the intercept's weights: the transient estimate's own noise).
    """
    if periods < 2:
        raise DataError(f"the transient's local polynomial needs at least 2 periods per record; got {periods}.")
    n_bins = X.shape[0]
    wanted = (degree + 1) + MIN_RESIDUAL_DOF
    centres = np.asarray(harmonics, dtype=int) * periods
    Xc = np.empty((centres.size, *X.shape[1:]), dtype=complex)
    var = np.empty((centres.size, *X.shape[1:]))
    for offsets, rows in _windows(centres, periods, n_bins, wanted):
        V = np.vander(offsets.astype(float) / max(abs(offsets).max(), 1), degree + 1, increasing=True)
        pinv = np.linalg.pinv(V)  # (R + 1, n_off): one solve shared by every line with these offsets
        hat = V @ pinv
        w = pinv[0]  # the intercept: the transient at the centre line
        window = X[centres[rows][:, None] + offsets[None, :]]  # (lines, n_off, ...)
        transient = np.tensordot(window, w, axes=([1], [0]))
        resid = window - np.einsum("ij,kj...->ki...", hat, window)
        sigma2 = np.sum(np.abs(resid) ** 2, axis=1) / (offsets.size - degree - 1)
        Xc[rows] = X[centres[rows]] - transient
        var[rows] = sigma2 * (1.0 + float(np.sum(w**2)))
    return Xc, var


def _windows(centres: np.ndarray, periods: int, n_bins: int, wanted: int):
    """Groups of centre lines sharing the same in-between offsets: the interior lines take the
    ``wanted`` nearest in-between lines on both sides; lines near DC or Nyquist take the nearest
    ones inside ``1 .. n_bins - 1`` (one group each)."""
    half = 1
    while 2 * (half - half // periods) < wanted:  # in-between lines within +-half
        half += 1
    base = np.array([r for r in range(-half, half + 1) if r % periods])
    interior = (centres - half >= 1) & (centres + half <= n_bins - 1)
    if interior.any():
        yield base, np.flatnonzero(interior)
    for row in np.flatnonzero(~interior):
        c = centres[row]
        candidates = np.array([r for r in range(1 - c, n_bins - c) if r % periods])
        if candidates.size < wanted:
            raise DataError(
                f"line {c // periods} has {candidates.size} in-between lines for its transient; needs {wanted}."
            )
        nearest = np.sort(candidates[np.argsort(np.abs(candidates), kind="stable")[:wanted]])
        yield nearest, np.array([row])
