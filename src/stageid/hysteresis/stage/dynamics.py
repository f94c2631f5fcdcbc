"""Unit-DC-gain discrete dynamics of a rate-dependent stage (amplifier + mechanics after the hysteresis).

The stage model of :mod:`.stage` runs the hysteresis output ``v`` through a discrete transfer
function ``G(z) = B(z) / A(z)`` of order ``n``,

    ``A(z) = 1 + a_1 z^-1 + ... + a_n z^-n``,  ``B(z) = b_0 + b_1 z^-1 + ... + b_n z^-n``,

with ``G(1) = 1`` (``sum b = sum a``), so the hysteresis keeps the output's units and a constant
(a sensor zero) passes through unchanged.  ``G`` starts at rest at the first sample, so the
filter of a column ``c`` is ``c[0] + G[c - c[0]]`` (:func:`unit_gain_filter`).

Fit (:func:`fit_unit_gain_dynamics`): Steiglitz-McBride iterations (output-error fit by repeated
prefiltered linear least squares) with the DC constraint eliminated,

    ``y(k) - v(k) = sum_i a_i (v(k) - y(k-i)) + sum_{i>=1} b_i (v(k-i) - v(k))``,

and unstable poles reflected into the unit circle after every step.

References: K. Steiglitz, L. McBride, IEEE Trans. Automatic Control 10 (1965) 461-464.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..._errors import IdentificationError, ModelError

__all__ = [
    "fit_unit_gain_dynamics",
    "unit_gain_filter",
    "unit_gain_coefficients",
    "zoh_resonance",
    "transfer_to_statespace",
    "statespace_to_transfer",
    "describe_pole",
    "ZERO_POLE",
]

#: Steiglitz-McBride iterations (the fit converges in a few on the records we tried).
SM_ITERATIONS = 8
#: A pole of smaller modulus is reported as "z ~ 0" (a one-sample delay within rounding).
ZERO_POLE = 1e-6


def zoh_resonance(frequency_hz: float, damping: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` in ``z^-1`` of ``wn^2 / (s^2 + 2 zeta wn s + wn^2)`` held over a sample (ZOH),
    scaled to unit DC gain (the sampled numerator is ``b_1 z^-1 + b_2 z^-2``)."""
    from scipy.signal import cont2discrete

    wn = 2 * np.pi * frequency_hz
    num, den, _ = cont2discrete(([wn**2], [1.0, 2 * damping * wn, wn**2]), dt, method="zoh")
    num = np.ravel(num)
    return num / (np.sum(num) / np.sum(den)), den


def unit_gain_filter(b: np.ndarray, a: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """``c[0] + G[c - c[0]]`` for every column of ``columns`` (shape (n_samples, p)), at rest at the first row.

    Equal to ``c[0] + scipy.signal.lfilter(b, a, c - c[0], axis=0)`` to the bit; a compiled
    loop over the samples with all columns at once (:mod:`.kernels.filters`).
    """
    from ..kernels.filters import unit_gain_columns

    c = np.ascontiguousarray(columns, dtype=float)
    if c.shape[0] == 0:
        return c.copy()
    return unit_gain_columns(*unit_gain_coefficients(b, a), c)


def unit_gain_coefficients(b: object, a: object) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` padded to one length and divided by ``a[0]``: the coefficients the filter of
    :func:`unit_gain_filter` runs (and exported code must run to agree with it)."""
    bb = np.atleast_1d(np.asarray(b, dtype=float))
    aa = np.atleast_1d(np.asarray(a, dtype=float))
    if aa[0] == 0:
        raise ModelError("the dynamics' leading denominator coefficient must not be zero.")
    m = max(bb.size, aa.size)  # lfilter's padding of the shorter polynomial and a[0] = 1
    return np.r_[bb, np.zeros(m - bb.size)] / aa[0], np.r_[aa, np.zeros(m - aa.size)] / aa[0]


def _stabilise(a: np.ndarray) -> np.ndarray:
    """Denominator with every root outside the unit circle reflected inside (same magnitude response)."""
    roots = np.roots(a)
    big = np.abs(roots) >= 0.999
    if not np.any(big):
        return a
    roots[big] = 0.999 / np.conj(roots[big])
    return np.real(np.poly(roots))


def _regressors(v: np.ndarray, y: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    rows = v.size - n
    X = np.empty((rows, 2 * n))
    for i in range(1, n + 1):
        X[:, i - 1] = v[n:] - y[n - i : v.size - i]
        X[:, n + i - 1] = v[n - i : v.size - i] - v[n:]
    return X, y[n:] - v[n:]


def fit_unit_gain_dynamics(
    pairs: list[tuple[np.ndarray, np.ndarray]], order: int, stride_rows: int = 200000
) -> tuple[np.ndarray, np.ndarray]:
    """Output-error fit of ``G = B/A`` of order ``order`` with ``G(1) = 1`` (Steiglitz-McBride).

    Parameters
    ----------
    pairs : list of (v, y)
        Per record, the hysteresis output and the measured output minus the record's offset,
        arrays of shape (n_samples,); both start at rest.
    order : int
        ``n >= 1``.
    stride_rows : int
        Most equation rows used per record (evenly strided blocks keep the lags exact).

    Returns
    -------
    b, a : ndarray of shape (order + 1,)

    Raises
    ------
    IdentificationError
        When the least-squares problem is singular (an input that does not excite the dynamics).
    """
    from scipy.signal import lfilter

    n = int(order)
    a = np.r_[1.0, np.zeros(n)]
    theta = None
    for _ in range(SM_ITERATIONS):
        Xs, ts = [], []
        for v, y in pairs:
            v0 = v - v[0]
            y0 = y - v[0]
            vf = lfilter([1.0], a, v0)
            yf = lfilter([1.0], a, y0)
            X, t = _regressors(vf, yf, n)
            Xs.append(X[:stride_rows])
            ts.append(t[:stride_rows])
        X = np.vstack(Xs)
        t = np.concatenate(ts)
        scale = np.linalg.norm(X, axis=0)
        if not np.all(scale > 0):
            raise IdentificationError(f"the records do not excite dynamics of order {n} (a regressor is zero).")
        theta, *_ = np.linalg.lstsq(X / scale, t, rcond=None)
        theta = theta / scale
        a = _stabilise(np.r_[1.0, theta[:n]])
    if theta is None or not np.all(np.isfinite(theta)):
        raise IdentificationError(f"the dynamics fit of order {n} failed (non-finite coefficients).")
    b_tail = theta[n:]
    b = np.r_[np.sum(a) - np.sum(b_tail), b_tail]
    return b, a


def transfer_to_statespace(b: np.ndarray, a: np.ndarray, dt: float, inputs=("v",), outputs=("y",)):
    """A discrete :class:`~stageid.models.StateSpaceModel` of ``B(z)/A(z)`` (coefficients in ``z^-1``)."""
    from ...models import StateSpaceModel
    from ...models.conversions import tf2ss_siso

    b = np.asarray(b, dtype=float)
    a = np.asarray(a, dtype=float)
    if a.size < 2:
        raise ModelError(f"dynamics need order >= 1; got a denominator of {a.size} coefficient(s).")
    with warnings.catch_warnings():  # scipy warns on trimming a tiny fitted b_0 (a one-sample delay)
        warnings.simplefilter("ignore")
        A, B, C, D = tf2ss_siso(b, a)
    return StateSpaceModel(A, B, C, D, dt=dt, inputs=inputs, outputs=outputs)


def statespace_to_transfer(model) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` in ``z^-1`` of a discrete SISO state-space model (numerator padded to ``n + 1``)."""
    from scipy.signal import ss2tf

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        b, a = ss2tf(model.A, model.B, model.C, model.D)
    return np.asarray(b, dtype=float).reshape(-1), np.asarray(a, dtype=float).reshape(-1)


def fit_hammerstein(records: list[tuple[np.ndarray, np.ndarray]], order: int) -> tuple[np.ndarray, np.ndarray]:
    """Starting ``(b, a)`` of ``y = o_j + G[Z_j w]`` by over-parametrised Steiglitz-McBride.

    ``A(q) y = sum_i sum_l (b_i w_l) Z_l(k - i) + A(1) o_j`` is linear in ``a`` and the products
    ``theta_il = b_i w_l`` (Bai 1998, over-parametrisation of Hammerstein models); the rank-one
    factor of ``theta`` gives ``b`` up to scale, fixed by ``G(1) = 1``.  Prefiltering by ``1/A``
    (Steiglitz-McBride) turns the equation error into an output error.  An alternating fit
    started from the rate-independent weights instead sticks where a lag imitates hysteresis.

    Parameters
    ----------
    records : list of (Z, y)
        Columns of shape (n_samples, p) (operator outputs, creep lags) and outputs (n_samples,).
    order : int

    Returns
    -------
    b, a : ndarray of shape (order + 1,)
    """
    from scipy.signal import lfilter

    n = int(order)
    J = len(records)
    p = records[0][0].shape[1]
    a = np.r_[1.0, np.zeros(n)]
    b = None
    for _ in range(SM_ITERATIONS // 2):
        Xs, ts = [], []
        for j, (Z, y) in enumerate(records):
            Zf = lfilter([1.0], a, Z - Z[:1], axis=0)
            yf = lfilter([1.0], a, y - y[0])
            rows = y.size - n
            X = np.zeros((rows, n + (n + 1) * p + J))
            for i in range(1, n + 1):
                X[:, i - 1] = -yf[n - i : y.size - i]
            for i in range(n + 1):
                X[:, n + i * p : n + (i + 1) * p] = Zf[n - i : y.size - i]
            X[:, n + (n + 1) * p + j] = lfilter([1.0], a, np.ones(y.size))[n:]
            Xs.append(X)
            ts.append(yf[n:])
        X = np.vstack(Xs)
        t = np.concatenate(ts)
        scale = np.linalg.norm(X, axis=0)
        scale[scale == 0] = 1.0
        sol = np.linalg.lstsq(X / scale, t, rcond=None)[0] / scale
        a = _stabilise(np.r_[1.0, sol[:n]])
        Theta = sol[n : n + (n + 1) * p].reshape(n + 1, p)
        U, s, Vt = np.linalg.svd(Theta, full_matrices=False)
        b = U[:, 0] * s[0]
        if np.sum(b) == 0:
            raise IdentificationError(f"the dynamics fit of order {n} failed (zero DC gain).")
        b = b * np.sum(a) / np.sum(b)
    if b is None or not np.all(np.isfinite(b)):
        raise IdentificationError(f"the dynamics fit of order {n} failed (non-finite coefficients).")
    return b, a


def describe_pole(z: complex, dt: float) -> str:
    """A discrete pole in words: its frequency ``|ln z| / (2 pi dt)`` when that is within the
    Nyquist frequency, else its place in the z-plane ("z ~ 0", "z = -0.3 (negative real axis)"):
    a pole near the origin or on the negative real axis has no continuous-time frequency that
    the sampling resolves, and a figure above Nyquist would mislead.

    Examples
    --------
    >>> describe_pole(0.9, 1e-4), describe_pole(-0.3, 1e-4), describe_pole(1e-13, 1e-4)
    ('167.7 Hz', 'z = -0.3 (negative real axis)', 'z ~ 0')
    """
    z = complex(z)
    if abs(z) < ZERO_POLE:
        return "z ~ 0"
    if abs(z.imag) <= 1e-12 * abs(z) and z.real < 0:
        return f"z = {z.real:.3g} (negative real axis)"
    s = np.log(z)
    if abs(s) > np.pi:  # beyond Nyquist: the pole sits close to the origin
        shown = f"{z.real:.3g}" if z.imag == 0 else f"{z.real:.3g}{z.imag:+.3g}j"
        return f"z = {shown} (near 0, faster than the sampling resolves)"
    return f"{abs(s) / (2 * np.pi * dt):.4g} Hz"
