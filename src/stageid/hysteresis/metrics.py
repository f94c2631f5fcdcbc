"""Error measures the modified-PI letter reports, each as a percentage.

* :func:`max_error_percent` -- "maximum modelling error" (letter: 5.31 % classical,
  1.02 % modified): ``100 max_k |y(k) - y_model(k)| / (max y - min y)``, the largest error
  over the record relative to the measured output range.
* :func:`rms_error_percent` -- the same with the RMS error.
* :func:`tracking_error_percent` -- "tracking error ... % full scale range (FSR)" (letter:
  11.0 % open loop, 4.8 % classical-PI inverse, 2.6 % modified-PI inverse; +-0.33 um of a
  3 um triangle is 11 %): ``100 max_k |y(k) - y_ref(k)| / (max y_ref - min y_ref)``.
* :func:`hysteresis_percent` -- "the hysteresis" of a loop (letter: 8.3 % open loop,
  2.9 % and 1.5 % compensated): the largest vertical width of the loop ``y`` against ``x``
  (``x`` = drive or desired output), i.e. the largest difference between the descending and
  the ascending branch at the same ``x``, relative to the output range ``max y - min y``.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError

__all__ = ["max_error_percent", "rms_error_percent", "tracking_error_percent", "hysteresis_percent"]


def _pair(a: object, b: object, what: str) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(a, dtype=float).reshape(-1) if np.ndim(a) <= 1 or np.shape(a)[-1] == 1 else None
    y = np.asarray(b, dtype=float).reshape(-1) if np.ndim(b) <= 1 or np.shape(b)[-1] == 1 else None
    if x is None or y is None or x.shape != y.shape:
        raise DataError(
            f"{what} needs two single-channel records of equal length; got shapes {np.shape(a)} and {np.shape(b)}."
        )
    if x.size < 2:
        raise DataError(f"{what} needs at least 2 samples; got {x.size}.")
    return x, y


def _pair_with_range(measured: object, predicted: object, name: str) -> tuple[np.ndarray, np.ndarray, float]:
    """The checked pair and the measured output's range, which the errors in % are relative to."""
    y, yh = _pair(measured, predicted, name)
    rng = float(np.ptp(y))
    if rng <= 0:
        raise DataError("the measured output is constant; the error in % of range is undefined.")
    return y, yh, rng


def max_error_percent(measured: object, predicted: object) -> float:
    """Largest absolute error in % of the measured output range.

    Parameters
    ----------
    measured, predicted : array_like of shape (n_samples,) or (n_samples, 1)

    Returns
    -------
    float

    Raises
    ------
    DataError
        On shape mismatch or a constant measured output.

    Examples
    --------
    >>> from stageid.hysteresis.metrics import max_error_percent
    >>> max_error_percent([0.0, 1.0, 2.0], [0.0, 1.1, 2.0])
    5.000000000000004
    """
    y, yh, rng = _pair_with_range(measured, predicted, "max_error_percent")
    return float(100.0 * np.max(np.abs(y - yh)) / rng)


def rms_error_percent(measured: object, predicted: object) -> float:
    """RMS error in % of the measured output range (see :func:`max_error_percent`)."""
    y, yh, rng = _pair_with_range(measured, predicted, "rms_error_percent")
    return float(100.0 * np.sqrt(np.mean((y - yh) ** 2)) / rng)


def tracking_error_percent(reference: object, output: object) -> float:
    """Largest tracking error in % of the reference's full-scale range (max - min).

    Examples
    --------
    >>> from stageid.hysteresis.metrics import tracking_error_percent
    >>> round(tracking_error_percent([0.0, 3.0, 0.0], [0.0, 2.67, 0.0]), 6)
    11.0
    """
    r, y = _pair(reference, output, "tracking_error_percent")
    fsr = float(np.ptp(r))
    if fsr <= 0:
        raise DataError("the reference is constant; the tracking error in % FSR is undefined.")
    return float(100.0 * np.max(np.abs(y - r)) / fsr)


def hysteresis_percent(x: object, y: object, n_levels: int = 200) -> float:
    """Largest loop width (descending minus ascending branch at equal ``x``) in % of the y range.

    The record is split into rising (``x`` increasing) and falling samples; each branch is
    averaged over its sweeps and interpolated onto ``n_levels`` levels of ``x`` spanning
    the range both branches cover; the result is ``100 max |y_down - y_up| / (max y - min y)``.

    Parameters
    ----------
    x : array_like of shape (n_samples,) or (n_samples, 1)
        The abscissa of the loop (drive voltage, or desired output in a tracking test).
    y : array_like of shape (n_samples,) or (n_samples, 1)
        The output.
    n_levels : int, default 200

    Returns
    -------
    float

    Raises
    ------
    DataError
        If ``x`` never rises and falls over a common range.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis.metrics import hysteresis_percent
    >>> t = np.linspace(0, 1, 401)
    >>> x = np.sin(2 * np.pi * t)
    >>> y = np.sin(2 * np.pi * t - 0.1)          # an ellipse-shaped loop
    >>> round(hysteresis_percent(x, y), 1)
    10.0
    """
    xx, yy = _pair(x, y, "hysteresis_percent")
    dx = np.diff(xx)
    branches = {}
    for sign in (1, -1):
        segs = []
        k = 0
        n = dx.size
        while k < n:
            if np.sign(dx[k]) == sign:
                j = k
                while j < n and np.sign(dx[j]) == sign:
                    j += 1
                segs.append((k, j))  # samples k..j inclusive are monotone
                k = j
            else:
                k += 1
        branches[sign] = segs
    if not branches[1] or not branches[-1]:
        raise DataError("hysteresis_percent needs x to rise and fall; got a monotone record.")
    lo = max(min(min(xx[a], xx[b]) for a, b in branches[s]) for s in (1, -1))
    hi = min(max(max(xx[a], xx[b]) for a, b in branches[s]) for s in (1, -1))
    if not hi > lo:
        raise DataError("the rising and falling parts of x do not overlap; no loop to measure.")
    levels = np.linspace(lo, hi, int(n_levels))
    curves = {}
    for s, segs in branches.items():
        acc = np.zeros_like(levels)
        cnt = np.zeros_like(levels)
        for a, b in segs:
            xs, ys = xx[a : b + 1], yy[a : b + 1]
            if s < 0:
                xs, ys = xs[::-1], ys[::-1]
            inside = (levels >= xs[0]) & (levels <= xs[-1])
            acc[inside] += np.interp(levels[inside], xs, ys)
            cnt[inside] += 1
        curves[s] = np.where(cnt > 0, acc / np.maximum(cnt, 1), np.nan)
    width = np.abs(curves[-1] - curves[1])
    width = width[np.isfinite(width)]
    return float(100.0 * np.max(width) / np.ptp(yy))
