"""The realised model's side of the delta method: its response and Jacobian, the similarity directions.

The realised model's response ``G = C (xI - A)^-1 B + D`` at points ``x`` (``z`` or ``s``,
:func:`response_points`), its Jacobian in the entries of ``A, B, C, D``
(:func:`model_jacobian`), the projection that drops the ``n^2`` similarity directions, which
do not change the response (:class:`TangentProjection`), and the response std of a parameter
covariance without forming the Jacobian (:func:`response_std`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...models.statespace import StateSpaceModel

__all__ = [
    "CHUNK",
    "GAUGE_TOLERANCE",
    "response_points",
    "model_jacobian",
    "TangentProjection",
    "response_std",
    "model_response",
]

#: Frequencies per block where a Jacobian over many frequencies is formed.
CHUNK = 256
#: Relative singular value (of the column-normalised Jacobian) below which a direction of
#: ``A, B, C, D`` counts as a similarity direction (no effect on the response).
GAUGE_TOLERANCE = 1e-9


def response_points(freqs_hz: np.ndarray, dt: float | None) -> np.ndarray:
    """``z = exp(j 2 pi f dt)`` (discrete) or ``s = j 2 pi f`` (continuous, ``dt`` None)."""
    f = np.asarray(freqs_hz, dtype=float)
    return 2j * np.pi * f if dt is None else np.exp(2j * np.pi * f * dt)


def model_jacobian(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, points: np.ndarray, feedthrough: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Response ``G = C (xI - A)^-1 B + D`` at ``points`` and its Jacobian in the matrix entries.

    ``dG = C R dA R B + C R dB + dC R B + dD`` with ``R = (xI - A)^-1``.

    Returns
    -------
    G : ndarray of shape (n_points, q, m), complex
    J : ndarray of shape (n_points, q, m, n_params), complex
        Columns: ``vec`` of ``A`` (row-major), ``B``, ``C``, then ``D`` when ``feedthrough``.

    Examples
    --------
    >>> import numpy as np
    >>> G, J = model_jacobian(np.array([[0.5]]), np.array([[1.0]]), np.array([[2.0]]), np.zeros((1, 1)), np.array([1.0]))
    >>> float(G[0, 0, 0].real), J[0, 0, 0].real.tolist()   # G = 2 / (z - 0.5) at z = 1
    (4.0, [8.0, 4.0, 2.0, 1.0])
    """
    n, m, q = A.shape[0], B.shape[1], C.shape[0]
    R = np.linalg.inv(points[:, None, None] * np.eye(n)[None] - A[None])  # (nz, n, n)
    CR = C[None] @ R
    RB = R @ B[None]
    G = CR @ B[None] + D[None]
    nz = points.size
    RBt = RB.transpose(0, 2, 1)  # (nz, m, n)
    JA = (CR[:, :, None, :, None] * RBt[:, None, :, None, :]).reshape(nz, q, m, n * n)
    JB = (CR[:, :, None, :, None] * np.eye(m)[None, None, :, None, :]).reshape(nz, q, m, n * m)
    JC = (np.eye(q)[None, :, None, :, None] * RBt[:, None, :, None, :]).reshape(nz, q, m, q * n)
    parts = [JA, JB, JC]
    if feedthrough:
        parts.append(np.broadcast_to(np.eye(q * m).reshape(1, q, m, q * m), (nz, q, m, q * m)))
    return G, np.concatenate(parts, axis=3)


@dataclasses.dataclass(frozen=True)
class TangentProjection:
    """First-order map of a weighted least-squares fit of a model's response to data on a grid.

    For ``min_x sum ||W^1/2 (G_model(x) - G_data)||^2`` at a minimum, ``dx = M [Re dG; Im dG]``;
    the model's response then moves by ``J(f) dx`` anywhere.  Stored in the reduced form
    ``dx = basis @ phi`` with ``phi = Re(functionals @ vec(dG))``.

    Attributes
    ----------
    functionals : ndarray of shape (r, n_points * q * m), complex
        ``phi = Re(functionals @ vec(dG))``: the data's weighted projection on the ``r``
        identifiable directions.
    basis : ndarray of shape (n_params, r)
        ``dx = basis @ phi``.
    """

    functionals: np.ndarray
    basis: np.ndarray

    @classmethod
    def from_jacobian(cls, J: np.ndarray, weights: np.ndarray, n_gauge: int = 0) -> TangentProjection:
        """From the Jacobian ``J`` (n_points, q, m, n_params) at the fit and the weight of every
        response entry (broadcastable to (n_points, q, m)); at most ``n_params - n_gauge``
        directions are kept (``n_gauge = n^2`` similarity directions of a minimal realisation)."""
        P = J.shape[3]
        sw = np.sqrt(np.broadcast_to(weights, J.shape[:3])).reshape(-1)
        Jw = J.reshape(-1, P) * sw[:, None]
        norms = np.sqrt(np.sum(np.abs(Jw) ** 2, axis=0))
        norms = np.where(norms > 0, norms, 1.0)
        Jn = Jw / norms[None, :]
        # the Gram matrix's eigenpairs are the SVD of the real-stacked [Re Jn; Im Jn] at a seventh
        # of its cost; its precision (eps relative to the largest eigenvalue) is why the kept
        # directions are also capped by the known number of similarity directions
        ev, V = np.linalg.eigh(Jn.real.T @ Jn.real + Jn.imag.T @ Jn.imag)  # Re(Jn^H Jn): two real products
        ev, V = ev[::-1], V[:, ::-1]
        ok = int(np.sum(ev > GAUGE_TOLERANCE**2 * max(float(ev[0]), 1e-300))) if ev.size else 0
        keep = min(ok, max(P - n_gauge, 1))
        s = np.sqrt(ev[:keep])
        Ur = (Jn @ V[:, :keep]) / s[None, :]  # complex (N, keep): Re-stacked left singular vectors
        functionals = np.conj(Ur).T * sw[None, :]  # Re(f @ dG) = Re(Ur)^T Re dG + Im(Ur)^T Im dG
        basis = (V[:, :keep] / s[None, :]) / norms[:, None]
        return cls(functionals, basis)

    def moments(self, cov: np.ndarray, pseudo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Cov(phi)`` (r, r) and ``E[phi conj(dG)^T]`` (r, N) for ``phi = Re(F vec dG)``, from
        ``E[dG dG^H]`` and ``E[dG dG^T]``."""
        F = self.functionals
        Fc, Fp = F @ cov, F @ pseudo
        phi = 0.5 * np.real(Fc @ np.conj(F).T + Fp @ F.T)
        return 0.5 * (phi + phi.T), 0.5 * (Fc + np.conj(Fp))

    def parameter_factor(self, phi_cov: np.ndarray) -> np.ndarray:
        """``L`` with ``L L^T = Cov(dx)`` (clipped at zero eigenvalues) from ``Cov(phi)``
        (:meth:`moments`), shape (n_params, r)."""
        ev, V = np.linalg.eigh(phi_cov)
        return self.basis @ (V * np.sqrt(np.clip(ev, 0.0, None))[None, :])


def response_std(
    abcd: tuple[np.ndarray, ...], factor: np.ndarray, points: np.ndarray, feedthrough: bool = True
) -> np.ndarray:
    """``sqrt(E|dG|^2)`` at ``points`` for parameters with ``Cov(dx) = factor factor^T``, shape
    (n_points, q, m); in blocks of ``CHUNK`` points.

    ``J dx`` for every column of ``factor`` without forming ``J``: ``C R (dA R B + dB) + dC R B
    + dD`` (:func:`model_jacobian`), about a quarter of the flops of ``J @ factor``.
    """
    A, B, C, D = abcd
    n, m, q, r = A.shape[0], B.shape[1], C.shape[0], factor.shape[1]
    LA = factor[: n * n].reshape(n, n, r)  # dA[a, b] per column
    LB = factor[n * n : n * n + n * m].reshape(n, m, r)
    LC = factor[n * n + n * m : n * n + n * m + q * n].reshape(q, n, r)
    LA_f = LA.reshape(n, n * r)  # [a, (b, col)]
    LB_f = LB.reshape(n, m * r)  # [a, (j, col)]
    LC_t = LC.transpose(1, 0, 2).reshape(n, q * r)  # [b, (i, col)]
    out = []
    for lo in range(0, points.size, CHUNK):
        x = points[lo : lo + CHUNK]
        nz = x.size
        R = np.linalg.inv(x[:, None, None] * np.eye(n)[None] - A[None])
        CR = (C[None] @ R).reshape(nz * q, n)  # [(z, i), a]
        RBt = (R @ B[None]).transpose(0, 2, 1)  # (nz, m, n): [z, j, b]
        # (C R dA) (R B) + C R dB: the real factor times the complex C R first (two real products
        # each), then the small product with R B per point, no regrouping of a large array
        T = (CR.real @ LA_f + 1j * (CR.imag @ LA_f)).reshape(nz, q, n, r)
        dG = np.matmul(RBt[:, None], T)  # (nz, q, m, r)
        dG += (CR.real @ LB_f + 1j * (CR.imag @ LB_f)).reshape(nz, q, m, r)
        RBf = RBt.reshape(nz * m, n)
        dG += (RBf.real @ LC_t + 1j * (RBf.imag @ LC_t)).reshape(nz, m, q, r).transpose(0, 2, 1, 3)
        if feedthrough:
            dG += factor[n * n + n * m + q * n :].reshape(q, m, r)[None]
        out.append(np.sqrt(np.sum(dG.real**2 + dG.imag**2, axis=3)))
    return np.concatenate(out, axis=0)


def model_response(model: StateSpaceModel, freqs_hz: np.ndarray) -> np.ndarray:
    """``C (xI - A)^-1 B + D`` at ``freqs_hz`` by numpy's batched solve, shape (n_freqs, q, m):
    ``model.frequency_response`` imports scipy.linalg, which costs a command-line run more than
    the uncertainty itself."""
    x = response_points(freqs_hz, model.dt)
    n = model.n_states
    if n == 0:
        return np.broadcast_to(model.D, (x.size,) + model.D.shape).astype(complex)
    R = np.linalg.solve(
        x[:, None, None] * np.eye(n)[None] - model.A[None], np.broadcast_to(model.B, (x.size,) + model.B.shape)
    )
    return model.C[None] @ R + model.D[None]
