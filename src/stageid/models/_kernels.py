"""Compiled inner loops for LTI simulation (numba, cached on disk)."""

from __future__ import annotations

import numpy as np


def _simulate_python(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, u: np.ndarray, x0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Reference recursion x(k+1) = A x(k) + B u(k), y(k) = C x(k) + D u(k)."""
    n_samples = u.shape[0]
    y = np.empty((n_samples, C.shape[0]))
    x = x0.copy()
    for k in range(n_samples):
        y[k] = C @ x + D @ u[k]
        x = A @ x + B @ u[k]
    return y, x


_compiled = None


def simulate_discrete(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, u: np.ndarray, x0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Run the exact discrete recursion; returns (y of shape (n_samples, p), final state)."""
    global _compiled
    if u.shape[0] < 2000 or A.shape[0] == 0:
        return _simulate_python(A, B, C, D, u, x0)
    if _compiled is None:
        import numba

        _compiled = numba.njit(cache=True, nogil=True)(_simulate_loop)
    y, x = _compiled(
        np.ascontiguousarray(A),
        np.ascontiguousarray(B),
        np.ascontiguousarray(C),
        np.ascontiguousarray(D),
        np.ascontiguousarray(u),
        x0.copy(),
    )
    return y, x


def _simulate_loop(A, B, C, D, u, x):  # pragma: no cover - compiled
    n_samples = u.shape[0]
    n = A.shape[0]
    m = B.shape[1]
    p = C.shape[0]
    y = np.empty((n_samples, p))
    xn = np.empty(n)
    for k in range(n_samples):
        for i in range(p):
            acc = 0.0
            for j in range(n):
                acc += C[i, j] * x[j]
            for j in range(m):
                acc += D[i, j] * u[k, j]
            y[k, i] = acc
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += A[i, j] * x[j]
            for j in range(m):
                acc += B[i, j] * u[k, j]
            xn[i] = acc
        for i in range(n):
            x[i] = xn[i]
    return y, x
