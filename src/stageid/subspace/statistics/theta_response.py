"""The frequency response implied by the identified model of eq. 9 (Cao & Chen 2013, section 2.1).

For a sinusoid ``u(k) = U z^k`` every block row of eq. 9 is an equation in ``G(z)``; the
``p q`` equations, solved by least squares, give the response of the Hankel-Toeplitz model
without realising it.  The frequency route of the realisation (:mod:`~stageid.subspace.realisation.frequency_domain`)
starts from this response; :func:`theta_response_std` adds its posterior spread and
:func:`response_systems` the equations themselves (used by :mod:`.window_covariance`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hankel_toeplitz import split_theta

__all__ = ["ThetaSpread", "response_bytes", "response_systems", "theta_frequency_response", "theta_response_std"]


@dataclass(frozen=True, eq=False)
class ThetaSpread:
    """``theta = [Gamma Phi D_p]`` of eq. 16 with the factors of its matrix-normal covariance
    ``Cov(vec theta) = column_cov (x) noise_cov``, in one set of coordinates.

    Attributes
    ----------
    theta : ndarray of shape (p q, 2 p m + p q)
    column_cov : ndarray of shape (2 p m + p q, 2 p m + p q)
        ``P``, the covariance of the columns (times ``p`` for the window overlap where the caller says so).
    noise_cov : ndarray of shape (p q, p q)
        ``Sigma``, the covariance of the eq. 9 error.
    horizon, n_inputs, n_outputs : int
    """

    theta: np.ndarray
    column_cov: np.ndarray
    noise_cov: np.ndarray
    horizon: int
    n_inputs: int
    n_outputs: int


def _response_system(
    theta: np.ndarray, horizon: int, m: int, q: int, zk: complex
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = horizon
    Gam, Phi, Dp = split_theta(theta, p, m, q)
    e_past = zk ** (np.arange(p) - p)
    e_fut = zk ** np.arange(p)
    rhs = np.einsum("rim,i->rm", Gam.reshape(p * q, p, m), e_past) + np.einsum(
        "rim,i->rm", Dp.reshape(p * q, p, m), e_fut
    )
    Phiw = np.einsum("riq,i->rq", Phi.reshape(p * q, p, q), e_past)
    lhs = np.kron(e_fut[:, None], np.eye(q)) - Phiw
    return lhs, rhs, np.concatenate([np.repeat(e_past, m), np.repeat(e_past, q), np.repeat(e_fut, m)])


def response_bytes(horizon: int, n_inputs: int, n_outputs: int, n_frequencies: int) -> float:
    """Memory :func:`response_systems` takes (a bound for :func:`theta_frequency_response`): its
    complex ``(n_freqs, p q, m + q)`` systems, their normal equations and temporaries (six)."""
    p, m, q = float(horizon), float(n_inputs), float(n_outputs)
    return 16.0 * 6.0 * n_frequencies * (p * q * (m + q) + 2.0 * p)


def response_systems(
    theta: np.ndarray, horizon: int, n_inputs: int, n_outputs: int, freqs: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The block-row equations of eq. 9 at every frequency: ``lhs G = rhs``.

    Returns ``lhs`` (n_freqs, p q, q), ``rhs`` (n_freqs, p q, m) and the powers of ``z`` they are
    built from, ``e_past = z^(i - p)`` and ``e_fut = z^i`` for ``i = 0..p-1`` (n_freqs, p).
    """
    p, m, q = horizon, n_inputs, n_outputs
    zs = np.exp(2j * np.pi * np.asarray(freqs, dtype=float) * dt)
    Gam, Phi, Dp = split_theta(theta, p, m, q)
    nz = zs.size
    e_past = zs[:, None] ** (np.arange(p) - p)[None, :]  # (nz, p)
    e_fut = zs[:, None] ** np.arange(p)[None, :]

    def weighted(e: np.ndarray, M: np.ndarray, k: int) -> np.ndarray:
        # sum_i e[z, i] M[r, i, :] for every z: two real products (nz, p) @ (p, pq k)
        M2 = np.ascontiguousarray(M.reshape(p * q, p, k).transpose(1, 0, 2)).reshape(p, p * q * k)
        return (e.real @ M2 + 1j * (e.imag @ M2)).reshape(nz, p * q, k)

    rhs = weighted(e_past, Gam, m) + weighted(e_fut, Dp, m)
    lhs = -weighted(e_past, Phi, q)
    lhs.reshape(nz, p, q, q)[:, :, np.arange(q), np.arange(q)] += e_fut[:, :, None]  # z^j I in block row j
    return lhs, rhs, e_past, e_fut


def _block_diagonal_sums(M: np.ndarray, p: int, r: int, c: int) -> np.ndarray:
    """``out[d + p - 1] = sum_i M_(i, i + d)`` over the ``p x p`` blocks (r, c) of ``M``: the block
    rows, last first, in rows of ``2 p`` blocks, read back in rows of ``2 p - 1`` (row ``p - 1 - i``
    moves ``i`` blocks right, which puts every block diagonal in one column)."""
    skew = np.zeros((p, 2 * p, r, c))
    skew[:, :p] = M.reshape(p, r, p, c).transpose(0, 2, 1, 3)[::-1]
    return skew.reshape(2 * p * p, r, c)[: p * (2 * p - 1)].reshape(p, 2 * p - 1, r, c).sum(axis=0)


def _response_coefficients(theta: np.ndarray, p: int, m: int, q: int) -> np.ndarray:
    """``C`` (4p - 1, q, q + m) with ``[lhs^H lhs, lhs^H rhs] = sum_x z^x C_(x + 2p - 1)`` on ``|z| = 1``
    (:func:`response_systems`: ``lhs_j = z^j I - sum_i z^(i-p) Phi_ji``, ``rhs_j = sum_i z^(i-p)
    Gamma_ji + z^i D_ji``): block-diagonal sums of ``Phi^T [Phi Gamma D_p]`` and ``[Phi Gamma D_p]``."""
    Gam, Phi, Dp = split_theta(theta, p, m, q)
    k = q + 2 * m
    blocks = np.concatenate([Phi.reshape(-1, p, q), Gam.reshape(-1, p, m), Dp.reshape(-1, p, m)], 2).reshape(p * q, -1)
    prod = _block_diagonal_sums(Phi.T @ blocks, p, q, k)  # sum_j Phi_ji^T [..]_j(i+d)
    own = _block_diagonal_sums(blocks, p, q, k)  # sum_j [..]_j(j+d)
    o = 2 * p - 1
    d = np.arange(1 - p, p) + o  # index of z^d
    C = np.zeros((4 * p - 1, q, q + m))
    C[o, :, :q] = p * np.eye(q)  # sum_j (z^j I)^H z^j I
    C[d, :, :q] += prod[:, :, :q]  # Phiw^H Phiw
    C[d - p, :, :q] -= own[:, :, :q]  # -(z^j I)^H Phiw_j
    C[2 * o - d + p, :, :q] -= own[:, :, :q].transpose(0, 2, 1)  # its conjugate transpose
    C[d - p, :, q:] += own[:, :, q : q + m]  # (z^j I)^H Gamma_j(z)
    C[d, :, q:] += own[:, :, q + m :] - prod[:, :, q : q + m]  # (z^j I)^H D_j(z) - Phiw^H Gamma(z)
    C[d + p, :, q:] -= prod[:, :, q + m :]  # -Phiw^H D(z)
    return C


def theta_frequency_response(
    theta: np.ndarray, horizon: int, n_inputs: int, n_outputs: int, freqs: np.ndarray, dt: float
) -> np.ndarray:
    """Frequency response implied by the identified Hankel-Toeplitz model (eq. 9).

    For a sinusoid ``u(k) = U z^k``, ``y(k) = G U z^k`` (``z = exp(j 2 pi f dt)``) every
    block row ``j`` of eq. 9 gives ``(z^j I - Phi_j(z)) G = Gamma_j(z) + D_j(z)``; the ``p q``
    equations (:func:`response_systems`) are solved for ``G`` by least squares, through their
    ``q x q`` normal equations evaluated from Laurent coefficients in ``z`` (never forming the
    ``(n_freqs, p q, q + m)`` systems).  The data determine the model's predictions only where
    they have energy, so this response is accurate over the excited band even when ``Gamma``,
    ``Phi`` and ``D_p`` individually are not (band-limited data).

    Returns
    -------
    ndarray of shape (n_freqs, n_outputs, n_inputs), complex
    """
    p, m, q = horizon, n_inputs, n_outputs
    C = _response_coefficients(theta, p, m, q)
    o = 2 * p - 1
    # z^x C_x + z^-x C_-x = cos(x w) (C_x + C_-x) + j sin(x w) (C_x - C_-x) on the unit circle
    angles = (2.0 * np.pi * dt) * np.asarray(freqs, dtype=float)[:, None] * np.arange(1, o + 1)[None, :]
    pos, neg = C[o + 1 :].reshape(o, -1), C[o - 1 :: -1].reshape(o, -1)
    normal = (C[o].reshape(1, -1) + np.cos(angles) @ (pos + neg)) + 1j * (np.sin(angles) @ (pos - neg))
    normal = normal.reshape(-1, q, q + m)
    return np.linalg.solve(normal[:, :, :q], normal[:, :, q:])


def theta_response_std(spread: ThetaSpread, freqs: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Response of :func:`theta_frequency_response` with its posterior standard deviation.

    With ``Cov(vec theta) = P (x) Sigma`` (matrix-normal posterior) and the first-order
    perturbation ``dG = L^+ dtheta V(z)`` of the block-row equations
    (``V = [e_past (x) I_m; e_past (x) G; e_fut (x) I_m]``), the variance of entry ``(i, j)``
    is ``(L^+ Sigma L^+H)_ii (V^H P V)_jj``.

    Returns
    -------
    G : ndarray of shape (n_freqs, q, m), complex
    std : ndarray of shape (n_freqs, q, m)
        Standard deviation of ``G`` (square root of ``E|dG|^2``).
    """
    theta, column_cov, noise_cov = spread.theta, spread.column_cov, spread.noise_cov
    p, m, q = spread.horizon, spread.n_inputs, spread.n_outputs
    zs = np.exp(2j * np.pi * np.asarray(freqs, dtype=float) * dt)
    G = np.empty((zs.size, q, m), dtype=complex)
    std = np.empty((zs.size, q, m))
    for i, zk in enumerate(zs):
        lhs, rhs, _ = _response_system(theta, p, m, q, zk)
        Lp = np.linalg.pinv(lhs)
        g = Lp @ rhs
        G[i] = g
        e_past = zk ** (np.arange(p) - p)
        e_fut = zk ** np.arange(p)
        V = np.concatenate(
            [np.kron(e_past[:, None], np.eye(m)), np.kron(e_past[:, None], g), np.kron(e_fut[:, None], np.eye(m))]
        )
        left = np.real(np.einsum("ir,rs,is->i", Lp, noise_cov, np.conj(Lp)))
        right = np.real(np.einsum("cj,cd,dj->j", np.conj(V), column_cov, V))
        std[i] = np.sqrt(np.clip(np.outer(left, right), 0.0, None))
    return G, std
