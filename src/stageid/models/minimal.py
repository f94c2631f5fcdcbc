"""Minimal realisation by orthogonal staircase reduction (no slycot needed).

The reduction works on the matrices (:func:`minimal_matrices`); :func:`minimal_realization`
applies it to any state-space model object with ``A, B, C, D`` fields.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

import numpy as np

__all__ = ["minimal_realization", "minimal_matrices", "controllable_basis"]

M = TypeVar("M")


def controllable_basis(A: np.ndarray, B: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis, shape (n, r), of the controllable subspace span[B, AB, A^2 B, ...].

    Built block by block (a Krylov staircase); each new block is orthogonalised twice
    against the basis found so far and its rank decided by an SVD with threshold ``tol``
    (for a single column its norm, which is that singular value).  The basis is written into
    one preallocated array: growing it by ``hstack`` per block copied it ``r`` times.
    """
    n = A.shape[0]
    Q = np.zeros((n, n), order="F")
    r = 0
    V = B
    while r < n:
        for _ in range(2):
            V = V - Q[:, :r] @ (Q[:, :r].T @ V)
        if V.size == 0:
            break
        if V.shape[1] == 1:
            s = float(np.linalg.norm(V))
            if not s > tol:
                break
            Qnew = V / s
        else:
            U, sv, _ = np.linalg.svd(V, full_matrices=False)
            k = int(np.sum(sv > tol))
            if k == 0:
                break
            Qnew = U[:, :k]
        k = min(Qnew.shape[1], n - r)
        Q[:, r : r + k] = Qnew[:, :k]
        r += k
        V = A @ Qnew[:, :k]
    return Q[:, :r]


def minimal_matrices(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, tol: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C)`` of the controllable and observable part (``D`` is unchanged).

    The subspaces are found with ``B`` and ``C`` scaled to unit norm: scaling them does not move
    the subspaces, and an absolute threshold would call every state of a small-gain plant (a
    stage in metres per volt, B ~ 1e-7) uncontrollable.  ``tol`` is the rank threshold on those
    scaled blocks; default ``1e-9 * max(1, ||A||)``.
    """
    if A.shape[0] == 0:
        return A, B, C
    if tol is None:
        tol = 1e-9 * max(1.0, np.linalg.norm(A, 2))
    Qc = controllable_basis(A, _unit(B), tol)
    Ac, Bc, Cc = Qc.T @ A @ Qc, Qc.T @ B, C @ Qc
    Qo = controllable_basis(Ac.T, _unit(Cc.T), tol)
    return Qo.T @ Ac @ Qo, Qo.T @ Bc, Cc @ Qo


def _unit(M: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(M, 2) if M.size else 0.0
    return M / norm if norm > 0 else M


def minimal_realization(model: M, tol: float | None = None) -> M:
    """Return an equivalent model with no uncontrollable or unobservable states.

    Parameters
    ----------
    model : StateSpaceModel
    tol : float, optional
        Rank threshold on ``B`` and ``C`` scaled to unit norm; default ``1e-9 * max(1, ||A||)``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.models import StateSpaceModel, minimal_realization
    >>> g = StateSpaceModel(np.diag([-1.0, -2.0]), [[1.0], [0.0]], [[1.0, 1.0]], [[0.0]])
    >>> minimal_realization(g).n_states
    1
    """
    if model.A.shape[0] == 0:  # type: ignore[attr-defined]
        return model
    A, B, C = minimal_matrices(model.A, model.B, model.C, tol)  # type: ignore[attr-defined]
    return replace(model, A=A, B=B, C=C, D=model.D.copy())  # type: ignore[attr-defined, type-var]
