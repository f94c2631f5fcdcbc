"""Minimal realisation by orthogonal staircase reduction (no slycot needed)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .statespace import StateSpaceModel

__all__ = ["minimal_realization", "controllable_basis"]


def controllable_basis(A: np.ndarray, B: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis, shape (n, r), of the controllable subspace span[B, AB, A^2 B, ...].

    Built block by block (a Krylov staircase); each new block is orthogonalised twice
    against the basis found so far and its rank decided by an SVD with threshold ``tol``.
    """
    n = A.shape[0]
    Q = np.zeros((n, 0))
    V = B
    while Q.shape[1] < n:
        for _ in range(2):
            V = V - Q @ (Q.T @ V)
        if V.size == 0:
            break
        U, s, _ = np.linalg.svd(V, full_matrices=False)
        r = int(np.sum(s > tol))
        if r == 0:
            break
        Qnew = U[:, :r]
        Q = np.hstack([Q, Qnew])
        V = A @ Qnew
    return Q


def minimal_realization(model: StateSpaceModel, tol: float | None = None) -> StateSpaceModel:
    """Return an equivalent model with no uncontrollable or unobservable states.

    Parameters
    ----------
    model : StateSpaceModel
    tol : float, optional
        Rank threshold; default ``1e-9 * max(1, ||A||, ||B||, ||C||)``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.models import StateSpaceModel, minimal_realization
    >>> g = StateSpaceModel(np.diag([-1.0, -2.0]), [[1.0], [0.0]], [[1.0, 1.0]], [[0.0]])
    >>> minimal_realization(g).n_states
    1
    """
    A, B, C = model.A, model.B, model.C
    if model.n_states == 0:
        return model
    if tol is None:
        scale = max(
            1.0, np.linalg.norm(A, 2), np.linalg.norm(B, 2) if B.size else 0.0, np.linalg.norm(C, 2) if C.size else 0.0
        )
        tol = 1e-9 * scale
    Qc = controllable_basis(A, B, tol)
    Ac, Bc, Cc = Qc.T @ A @ Qc, Qc.T @ B, C @ Qc
    Qo = controllable_basis(Ac.T, Cc.T, tol)
    Am, Bm, Cm = Qo.T @ Ac @ Qo, Qo.T @ Bc, Cc @ Qo
    return replace(model, A=Am, B=Bm, C=Cm, D=model.D.copy())
