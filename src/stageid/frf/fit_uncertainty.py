"""Uncertainty of a model fitted to frequency-response data, from the data's standard deviation.

:class:`~stageid.frf.identification.FRDIdentification` ends with the weighted output-error fit
``min_x sum_k w_k ||G_model(x; z_k) - G_k||^2`` over all entries ``x`` of ``A, B, C, D`` (in
its internal discrete coordinates at ``T``, columns scaled, the delay removed).  At the
minimum a perturbation ``e`` of the data moves the parameters by ``dx = H^+ Re(J^H W e)``
(``H = Re(J^H W J)``, Gauss-Newton; the pseudo-inverse drops the ``n^2`` similarity directions,
which do not move the response), so with independent circular errors of variance
``sigma_k^2`` per entry (the FRF's ``std``; what Welch, LPM and periodic averaging estimate)

    Cov(dx) = H^+ Re(J^H diag(w^2 sigma^2 / 2) J) H^+

(a sandwich: the weights need not be ``1 / sigma^2``), and the model's response moves by
``J(f) dx`` at any frequency.  Without a ``std`` the variance is estimated from the weighted
residual, ``sigma_k^2 = s^2 / w_k`` with ``s^2 = 2 RSS_w / (2 N - r)`` (then a model bias
counts as noise).  The order and the delay are held fixed: their choice is not counted.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..subspace.uncertainty import GAUGE_TOLERANCE, model_jacobian, response_std

__all__ = ["FitCovariance", "fit_covariance"]

#: Frequencies per block when the Gram sums are accumulated (bounds the Jacobian's memory).
CHUNK = 128


@dataclasses.dataclass(frozen=True)
class FitCovariance:
    """The fitted model in the fit's coordinates and the covariance factor of its entries.

    Attributes
    ----------
    A, B, C, D : ndarrays
        The refined model at sample time ``T`` (columns divided by ``scale``, delay removed).
    T : float
    scale : ndarray of shape (n_inputs,)
    factor : ndarray of shape (n_params, r)
        ``Cov(vec A, vec B, vec C, vec D) = factor factor^T``.
    noise_source : str
        ``"std"`` (the data's) or ``"residual"`` (estimated from the fit).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    T: float
    scale: np.ndarray
    factor: np.ndarray
    noise_source: str

    def response_std(self, points: np.ndarray) -> np.ndarray:
        """``sqrt(E|dG|^2)`` at unit-circle points ``z`` of the fit, in the data's units (n, q, m)."""
        return response_std((self.A, self.B, self.C, self.D), self.factor, points) * self.scale[None, None, :]


def _grams(abcd: tuple[np.ndarray, ...], zs: np.ndarray, w: np.ndarray, var: np.ndarray) -> tuple[np.ndarray, ...]:
    """``Re(J^H W J)`` and ``Re(J^H diag(w^2 var / 2) J)``, accumulated over frequency blocks."""
    H = M = None
    for lo in range(0, zs.size, CHUNK):
        sl = slice(lo, lo + CHUNK)
        _, J = model_jacobian(*abcd, zs[sl], True)
        J2 = J.reshape(-1, J.shape[3])
        wk = np.broadcast_to(w[sl][:, None, None], J.shape[:3]).reshape(-1)
        h = np.real(np.conj(J2).T @ (J2 * wk[:, None]))
        g = np.real(np.conj(J2).T @ (J2 * (wk**2 * var[sl].reshape(-1) / 2.0)[:, None]))
        H = h if H is None else H + h
        M = g if M is None else M + g
    assert H is not None and M is not None
    return H, M


def _pseudo_inverse(H: np.ndarray, n_gauge: int) -> np.ndarray:
    """``H^+`` without the similarity directions (at most ``P - n_gauge`` kept), column-normalised."""
    d = np.sqrt(np.clip(np.diag(H), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    ev, V = np.linalg.eigh(H / np.outer(d, d))
    ev, V = ev[::-1], V[:, ::-1]
    ok = int(np.sum(ev > GAUGE_TOLERANCE**2 * max(float(ev[0]), 1e-300))) if ev.size else 0
    keep = min(ok, max(H.shape[0] - n_gauge, 1))
    Vk = V[:, :keep] / d[:, None]
    return (Vk / ev[:keep][None, :]) @ Vk.T


def fit_covariance(
    abcd: tuple[np.ndarray, ...],
    G: np.ndarray,
    zs: np.ndarray,
    w: np.ndarray,
    std: np.ndarray | None,
    T: float,
    scale: np.ndarray,
) -> FitCovariance:
    """The covariance of the refined fit (see the module docstring).

    Parameters
    ----------
    abcd : the refined ``(A, B, C, D)`` at ``T``
    G : ndarray of shape (n_freqs, q, m)
        The response it was fitted to (columns scaled, delay removed).
    zs : ndarray of shape (n_freqs,)
        The fit's points ``exp(j 2 pi f_fit T)``.
    w : ndarray of shape (n_freqs,)
        The fit's weights.
    std : ndarray of shape (n_freqs, q, m) or None
        The data's std in the same (scaled) coordinates; None: from the residual.
    """
    A = abcd[0]
    nz, q, m = G.shape
    n_gauge = A.shape[0] ** 2
    if std is not None:
        var, source = np.asarray(std, dtype=float) ** 2, "std"
    else:
        res = np.abs(_response(abcd, zs) - G) ** 2
        rss = float(np.sum(w[:, None, None] * res))
        n_params = A.size + abcd[1].size + abcd[2].size + abcd[3].size - n_gauge
        dof = max(2 * nz * q * m - n_params, 1)
        var = np.broadcast_to((2.0 * rss / dof) / np.maximum(w, 1e-300)[:, None, None], G.shape)
        source = "residual"
    H, M = _grams(abcd, zs, w, var)
    Hp = _pseudo_inverse(H, n_gauge)
    cov = Hp @ M @ Hp
    ev, V = np.linalg.eigh(0.5 * (cov + cov.T))
    factor = V * np.sqrt(np.clip(ev, 0.0, None))[None, :]
    return FitCovariance(*(np.array(x, dtype=float) for x in abcd), float(T), np.asarray(scale, float), factor, source)


def _response(abcd: tuple[np.ndarray, ...], zs: np.ndarray) -> np.ndarray:
    A, B, C, D = abcd
    R = np.linalg.inv(zs[:, None, None] * np.eye(A.shape[0])[None] - A[None])
    return C[None] @ R @ B[None] + D[None]
