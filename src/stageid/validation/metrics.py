"""Error metrics shared by every method: time-domain fit and frequency-response error.

All functions take time-first arrays ``(n_samples, n_channels)`` (1-D is one channel)
and return one value per channel.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["fit_percent", "nrmse", "rms_error", "relative_response_error"]


def _pair(measured: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    y = np.asarray(measured, dtype=float)
    yh = np.asarray(predicted, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    yh = yh[:, None] if yh.ndim == 1 else yh
    if y.shape != yh.shape:
        raise DataError(f"measured and predicted outputs must have the same shape; got {y.shape} and {yh.shape}.")
    return y, yh


def fit_percent(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Normalised fit ``100 (1 - ||y - yhat|| / ||y - mean(y)||)`` per channel (MATLAB's ``compare``).

    100 is a perfect fit, 0 is no better than the mean, negative is worse.  The fit of a
    constant measured channel (``y == mean(y)``) is undefined and returned as NaN (never
    ``-inf``): report it as "n/a", write it to JSON as ``null``.

    Parameters
    ----------
    measured, predicted : array_like of shape (n_samples, n_channels) or (n_samples,)

    Returns
    -------
    ndarray of shape (n_channels,)
        Fit in percent; NaN for constant measured channels.

    Raises
    ------
    DataError
        When the shapes differ.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.validation import fit_percent
    >>> y = np.sin(np.linspace(0, 6, 50))
    >>> float(fit_percent(y, y)[0])
    100.0
    >>> fit_percent(np.ones(5), np.zeros(5))  # constant channel: undefined
    array([nan])
    """
    y, yh = _pair(measured, predicted)
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging prediction: -inf, no warning
        den = _norm(y - y.mean(axis=0))
        num = _norm(y - yh)
        out = np.full(den.shape, np.nan)
        # a constant channel leaves only the rounding of its mean, at most n eps |y| per sample
        moving = den > y.shape[0] * np.finfo(float).eps * _norm(y)
        out[moving] = 100.0 * (1.0 - num[moving] / den[moving])
    return out


def _norm(x: np.ndarray) -> np.ndarray:
    """2-norm of each column; a column whose squares overflow is scaled by its largest entry first."""
    with np.errstate(over="ignore", invalid="ignore"):
        n = np.linalg.norm(x, axis=0)
        big = np.isinf(n) & np.all(np.isfinite(x), axis=0)
        if big.any():
            scale = np.max(np.abs(x[:, big]), axis=0)
            n[big] = scale * np.linalg.norm(x[:, big] / scale, axis=0)
    return n


def nrmse(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """RMS error divided by the measured channel's range (peak-to-peak), per channel.

    Not MATLAB's NRMSE (``goodnessOfFit``), which is ``1 - fit / 100``: the error over the
    output's deviation from its mean.  ``stageid validate`` prints this one as "RMS error
    ... % of range".
    """
    y, yh = _pair(measured, predicted)
    return np.sqrt(np.mean((y - yh) ** 2, axis=0)) / np.ptp(y, axis=0)


def rms_error(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Root-mean-square error per channel."""
    y, yh = _pair(measured, predicted)
    return np.sqrt(np.mean((y - yh) ** 2, axis=0))


def relative_response_error(estimated: np.ndarray, true: np.ndarray, per: str = "column") -> np.ndarray:
    """Largest frequency-response error relative to the true response's size.

    Parameters
    ----------
    estimated, true : ndarray of shape (n_freqs, n_outputs, n_inputs)
    per : {"column", "entry"}
        "column": each entry's error divided by the largest true gain of its input column
        over the band (so a small coupling entry is judged against its column's main gain); "entry": divided
        by that entry's own largest true gain.

    Returns
    -------
    ndarray of shape (n_outputs, n_inputs)
        ``max_f |G_est - G_true| / scale``.
    """
    if estimated.shape != true.shape or estimated.ndim != 3:
        raise DataError(
            f"responses must both have shape (n_freqs, n_outputs, n_inputs); got {estimated.shape} and {true.shape}."
        )
    err = np.max(np.abs(estimated - true), axis=0)
    mag = np.abs(true)
    if per == "column":
        scale = np.max(mag, axis=(0, 1))[None, :]
    elif per == "entry":
        scale = np.max(mag, axis=0)
    else:
        raise DataError(f"`per` must be 'column' or 'entry'; got {per!r}.")
    return err / scale
