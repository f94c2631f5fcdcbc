"""The eq. 9 side of the delta method: the covariance of the eq. 9 response across a grid.

``dG_9 = L^+ dtheta V(z)`` (first order in the block-row equations of eq. 9) with the
matrix-normal posterior ``Cov(vec theta) = P (x) Sigma`` (:func:`eq9_response_covariance`), on
a grid coarse enough to keep the covariance small (:func:`covariance_grid`), in the
noise-whitened coordinates the realisation fits (:func:`~.realisation.weighting.weighted_parts`,
:func:`column_solve`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..map.posterior import Posterior
from ..realisation.weighting import output_weights, weight_scales, weighted_parts
from ..statistics.theta_response import ThetaSpread
from ..statistics.window_covariance import response_directions

# weighted_parts is re-exported (the uncertainty package's name for it)
__all__ = ["MAX_COVARIANCE_ENTRIES", "eq9_response_covariance", "covariance_grid", "weighted_parts", "column_solve"]

#: Most response entries (frequencies x outputs x inputs) of the eq. 9 covariance in ``"delta"``.
MAX_COVARIANCE_ENTRIES = 300


def eq9_response_covariance(
    spread: ThetaSpread, freqs: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The eq. 9 response on a grid and the covariance of its error across the whole grid.

    ``dG_k = L_k^+ dtheta V_k`` (``theta_response_std``) with ``Cov(vec theta) = P (x) Sigma``
    gives ``E[dG_k(i,j) conj(dG_l(i',j'))] = (L_k^+ Sigma L_l^+H)_(ii') (V_k^T P conj V_l)_(jj')``
    and the pseudo-covariance (no conjugate) likewise: ``theta`` is real, so both are needed.

    Returns
    -------
    G : ndarray of shape (n_freqs, q, m), complex
    cov, pseudo : ndarrays of shape (n_freqs q m, n_freqs q m), complex (``vec`` in (k, i, j) order)
    """
    p, m, q = spread.horizon, spread.n_inputs, spread.n_outputs
    G, Lp, V = response_directions(spread.theta, p, m, q, freqs, dt)
    nz = G.shape[0]
    column_cov, noise_cov = spread.column_cov, spread.noise_cov
    PV = column_cov @ V.real + 1j * (column_cov @ V.imag)  # a real matrix: half the flops of complex
    A_c = (V.T @ np.conj(PV)).reshape(nz, m, nz, m)
    A_p = (V.T @ PV).reshape(nz, m, nz, m)
    L2 = Lp.reshape(nz * q, p * q)
    LS = L2 @ noise_cov
    B_c = (LS @ np.conj(L2).T).reshape(nz, q, nz, q)
    B_p = (LS @ L2.T).reshape(nz, q, nz, q)
    N = nz * q * m
    cov = (B_c[:, :, None, :, :, None] * A_c[:, None, :, :, None, :]).reshape(N, N)
    pseudo = (B_p[:, :, None, :, :, None] * A_p[:, None, :, :, None, :]).reshape(N, N)
    return G, cov, pseudo


def covariance_grid(
    band: tuple[float, float], n_frequencies: int, n_entries: int, cap: int = MAX_COVARIANCE_ENTRIES
) -> np.ndarray:
    """The realisation's grid (``n_frequencies`` evenly over ``band``), every ``s``-th point kept so
    that at most ``cap`` response entries enter the covariance.

    The realisation's least-squares fit on an even grid approximates an integral over the band;
    a coarser even grid approximates the same integral as long as it resolves the response, and
    the covariance costs ``(n_freqs q m)^2`` memory and ``r (n_freqs q m)^2`` work.
    """
    stride = max(1, int(np.ceil(n_frequencies * n_entries / cap)))
    return np.linspace(band[0], band[1], n_frequencies)[::stride]


def column_solve(post: Posterior) -> Callable[[np.ndarray], np.ndarray]:
    """``V -> P V`` in the coordinates of :func:`~.realisation.weighting.weighted_parts` (without its factor ``p``): a
    solve with the posterior information instead of its inverse (``Posterior.covariance``), the
    same definiteness test (Cholesky) and the same fallback (the pseudo-inverse)."""
    _, c = weight_scales(output_weights(post), post.horizon, post.n_inputs)
    info = post.information
    try:
        np.linalg.cholesky(info)
        return lambda V: c[:, None] * _real_apply(lambda X: np.linalg.solve(info, X), c[:, None] * V)
    except np.linalg.LinAlgError:
        pinv = np.linalg.pinv(info, hermitian=True)
        return lambda V: c[:, None] * _real_apply(lambda X: pinv @ X, c[:, None] * V)


def _real_apply(op: Callable[[np.ndarray], np.ndarray], V: np.ndarray) -> np.ndarray:
    """``op(V)`` for a linear ``op`` with a real matrix and a complex ``V``: one real call on
    ``[Re V, Im V]`` (a complex right-hand side would make numpy factor the matrix as complex)."""
    if not np.iscomplexobj(V):
        return op(V)
    k = V.shape[1]
    X = op(np.hstack([V.real, V.imag]))
    return X[:, :k] + 1j * X[:, k:]
