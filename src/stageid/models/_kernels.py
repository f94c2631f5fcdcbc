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
    S = np.block([[C, D], [A, B]])
    return _compiled(S, C.shape[0], np.ascontiguousarray(u), x0.astype(float, copy=True))


def _simulate_loop(S, n_outputs, u, x):  # pragma: no cover - compiled
    """``[y(k); x(k+1)] = S [x(k); u(k)]`` with ``S = [[C, D], [A, B]]``: both equations in one product."""
    n_samples = u.shape[0]
    n = x.shape[0]
    m = u.shape[1]
    y = np.empty((n_samples, n_outputs))
    v = np.empty(n + m)  # [x(k); u(k)]
    w = np.empty(S.shape[0])  # [y(k); x(k+1)]
    for k in range(n_samples):
        for j in range(n):
            v[j] = x[j]
        for j in range(m):
            v[n + j] = u[k, j]
        for i in range(S.shape[0]):
            acc = 0.0
            for j in range(n + m):
                acc += S[i, j] * v[j]
            w[i] = acc
        for i in range(n_outputs):
            y[k, i] = w[i]
        for i in range(n):
            x[i] = w[n_outputs + i]
    return y, x
