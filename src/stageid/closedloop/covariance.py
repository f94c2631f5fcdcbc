"""Covariance of the prediction-error parameters (Shakir & Kim, eq. 13-14; Ljung 1999, sec. 9.3).

At the minimum of eq. 13 the parameter error is, to first order, ``d theta = -(J^T J)^-1 J^T e``
with ``J = d e / d theta`` (the Gauss-Newton approximation of the Hessian).  Two estimates of
its covariance:

* ``"white"``: ``sigma^2 (J^T J)^-1`` with ``sigma^2 = sum e^2 / (N - n_par)`` — exact when the
  prediction errors are white, as a correct ARMAX/BJ noise model makes them;
* ``"sandwich"`` (default): ``(J^T J)^-1 (J^T Lambda J) (J^T J)^-1`` with ``Lambda`` the
  residuals' autocovariance, estimated through a Bartlett lag window (Ljung 1999, eq. 9.42 for
  an output-error model under coloured noise).  In closed loop an output-error fit leaves
  ``e = S v``, the measurement noise shaped by the sensitivity, far from white: the white
  formula is then wrong by the ratio of ``|S|^2`` where the model is sensitive to its average
  (studies/uncertainty_closedloop/RESULTS.md compares both).

``J^T J`` is often ill-conditioned (high orders, near pole-zero cancellations): columns are
scaled to unit norm and the inverse is a pseudo-inverse that drops directions below
``rcond`` of the largest singular value, which the data do not determine (they carry no
variance a first-order propagation could trust; see :mod:`~stageid.closedloop.uncertainty`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from .._errors import IdentificationError
from ..data import Experiment
from ..models import StateSpaceModel
from ..runtime.threads import single_blas_thread
from .pem import jacobian
from .polynomial import PolynomialModel, residual_parts

__all__ = [
    "COVARIANCE_METHODS",
    "ClosedLoopCovariance",
    "closed_loop_covariance",
    "model_orders",
    "pem_covariance",
    "transfer_gradient",
    "transfer_gradient_at",
]

COVARIANCE_METHODS = ("sandwich", "white")


def model_orders(model: PolynomialModel) -> dict[str, int]:
    """The five orders of ``model`` in the layout of :func:`~stageid.closedloop.polynomial.pack`."""
    return {
        "na": model.A.size - 1,
        "nb": model.B.size,
        "nc": model.C.size - 1,
        "nd": model.D.size - 1,
        "nf": model.F.size - 1,
    }


def pem_covariance(
    model: PolynomialModel,
    u: Sequence[np.ndarray],
    y: Sequence[np.ndarray],
    method: str = "sandwich",
    max_lag: int | None = None,
    rcond: float = 1e-10,
) -> np.ndarray:
    """Covariance of the parameters of a prediction-error fit, shape (n_par, n_par).

    Parameters
    ----------
    model : PolynomialModel
        The fit at its optimum (parameters in the order of ``pack(A, B, C, D, F)``).
    u, y : sequences of ndarray of shape (n_samples,)
        The records it was fitted on, exactly as given to :func:`~stageid.closedloop.pem.pem`.
    method : {"sandwich", "white"}
        See the module notes.
    max_lag : int, optional
        Length of the Bartlett lag window of ``"sandwich"`` (default ``min(n / 10, 1000)``
        samples of the longest record: longer than the sensitivity's memory at 5 kHz, short
        enough for a stable estimate).
    rcond : float
        Relative cut-off of the pseudo-inverse of the scaled ``J^T J``.

    Returns
    -------
    ndarray of shape (n_par, n_par)

    Raises
    ------
    IdentificationError
        Unknown ``method``, or fewer samples than parameters.

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> from stageid.closedloop import pem
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(4000)
    >>> y = ss.lfilter([0, 0.3], [1, -0.8], u) + 0.1 * rng.standard_normal(4000)
    >>> m = pem(u, y, "oe", {"nb": 1, "nf": 1})
    >>> P = pem_covariance(m, [u], [y], "white")
    >>> bool(np.all(np.sqrt(np.diag(P)) < 0.01))
    True
    """
    if method not in COVARIANCE_METHODS:
        raise IdentificationError(
            f"`method` of the PEM covariance must be one of {COVARIANCE_METHODS}; got {method!r}."
        )
    orders = model_orders(model)
    n_par = sum(orders.values())
    polys = (model.A, model.B, model.C, model.D, model.F)
    segs = [(np.asarray(uu, dtype=float).reshape(-1), np.asarray(yy, dtype=float).reshape(-1)) for uu, yy in zip(u, y)]
    n_total = sum(uu.size for uu, _ in segs)
    if n_total <= n_par:
        raise IdentificationError(f"the PEM covariance needs more samples than its {n_par} parameters; got {n_total}.")
    lag = int(max_lag) if max_lag is not None else min(max(uu.size for uu, _ in segs) // 10, 1000)
    bread = np.zeros((n_par, n_par))
    meat = np.zeros((n_par, n_par))
    sum_e2 = 0.0
    for uu, yy in segs:
        parts = residual_parts(*polys, model.nk, uu, yy)
        J = jacobian(*polys, model.nk, orders, uu, yy, parts=parts)
        e = parts[2]
        bread += J.T @ J
        sum_e2 += float(e @ e)
        if method == "sandwich":
            meat += _lag_window_meat(J, e, lag)
    if method == "white":
        meat = sum_e2 / (n_total - n_par) * bread
    else:
        meat *= n_total / (n_total - n_par)  # the same degrees-of-freedom correction as sigma^2
    Binv = _scaled_pinv(bread, rcond)
    cov = Binv @ meat @ Binv
    return 0.5 * (cov + cov.T)


def _lag_window_meat(J: np.ndarray, e: np.ndarray, max_lag: int) -> np.ndarray:
    """``sum_{t,s} J_t w(t-s) R(t-s) J_s^T``: ``J^T Lambda J`` with a Bartlett-tapered autocovariance.

    Evaluated in the frequency domain (zero-padded, so no circular wrap): ``R`` from the
    periodogram, tapered in lag, transformed back to a smoothed spectrum ``Phi``, then
    ``Re sum_k c_k Phi_k conj(J_k) J_k^T / n_fft``.
    """
    n = e.size
    n_fft = sfft.next_fast_len(2 * n)
    E = sfft.rfft(e, n_fft)
    R = sfft.irfft(np.abs(E) ** 2 / n, n_fft)  # biased autocovariance, lags 0..n-1 then negative
    lag = np.minimum(np.arange(n_fft), n_fft - np.arange(n_fft))
    R *= np.clip(1.0 - lag / (max_lag + 1.0), 0.0, None)
    Phi = np.clip(sfft.rfft(R).real, 0.0, None)  # a spectrum: rounding below zero clipped
    Jf = sfft.rfft(J, n_fft, axis=0)
    c = np.full(Phi.size, 2.0)
    c[0] = 1.0
    if n_fft % 2 == 0:
        c[-1] = 1.0
    W = Jf * np.sqrt(c * Phi)[:, None]
    return (W.conj().T @ W).real / n_fft


def _scaled_pinv(H: np.ndarray, rcond: float) -> np.ndarray:
    """Pseudo-inverse of a Gram matrix after scaling it to a unit diagonal."""
    d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
    Hs = H / d[:, None] / d[None, :]
    return np.linalg.pinv(Hs, rcond=rcond, hermitian=True) / d[:, None] / d[None, :]


def transfer_gradient(model: PolynomialModel, freqs_hz: np.ndarray) -> np.ndarray:
    """``d G(e^{j w dt}) / d theta`` of ``G = q^-nk B / (A F)``, complex, shape (n_freqs, n_par).

    Columns in the order of :func:`~stageid.closedloop.polynomial.pack`; the noise polynomials
    ``C, D`` do not enter ``G`` and get zero columns.
    """
    return transfer_gradient_at(model, np.exp(2j * np.pi * np.asarray(freqs_hz, dtype=float) * model.dt))


def transfer_gradient_at(model: PolynomialModel, z: np.ndarray) -> np.ndarray:
    """``d G(z) / d theta`` at any complex ``z`` (as :func:`transfer_gradient`), shape (n_z, n_par)."""
    orders = model_orders(model)
    q = 1.0 / np.asarray(z, dtype=complex).reshape(-1)  # the backward shift q^-1
    pv = np.polynomial.polynomial.polyval
    A, F = pv(q, model.A), pv(q, model.F)
    G = q**model.nk * pv(q, model.B) / (A * F)
    cols = [-G[:, None] * q[:, None] ** np.arange(1, orders["na"] + 1) / A[:, None]]
    cols.append(q[:, None] ** (model.nk + np.arange(orders["nb"])) / (A * F)[:, None])
    cols.append(np.zeros((q.size, orders["nc"] + orders["nd"]), complex))
    cols.append(-G[:, None] * q[:, None] ** np.arange(1, orders["nf"] + 1) / F[:, None])
    return np.hstack(cols)


@dataclass(frozen=True, eq=False)
class ClosedLoopCovariance:
    """What the propagation to the plant needs, kept on the result (no data).

    Attributes
    ----------
    covariances : dict
        ``(i, j) -> ndarray (n_par, n_par)``, the covariance of pair ``T_ij``'s parameters.
        Pairs are independent: each uses its own output channel or its own experiment.
    band_freqs : ndarray
        The grid (Hz) the reduction was fitted on.
    reference_filter : StateSpaceModel or None
        ``M_r`` of a two-degree-of-freedom law (None: ``M_r = M``).
    method : str
        "sandwich" or "white".
    """

    covariances: dict
    band_freqs: np.ndarray
    reference_filter: StateSpaceModel | None
    method: str


@single_blas_thread
def closed_loop_covariance(
    groups: Mapping[int, Sequence[Experiment]],
    models: Mapping[tuple[int, int], PolynomialModel],
    band_freqs: np.ndarray,
    reference_filter: StateSpaceModel | None = None,
    method: str = "sandwich",
) -> ClosedLoopCovariance:
    """:func:`pem_covariance` of every pair, on the records :func:`~stageid.closedloop.loop_model.identify_pairs`
    fitted it on (deviations from the loop at rest, :func:`~stageid.closedloop.loop_model.at_rest`)."""
    covs = {}
    for j, group in groups.items():
        r = [e.u[:, j] for e in group]
        for i in range(group[0].n_outputs):
            y = [e.y[:, i] for e in group]
            covs[(i, j)] = pem_covariance(models[(i, j)], r, y, method)
    return ClosedLoopCovariance(covs, np.asarray(band_freqs, dtype=float).copy(), reference_filter, method)
