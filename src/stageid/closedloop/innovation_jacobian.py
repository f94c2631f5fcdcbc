"""The analytic Jacobian of the innovation-form predictor's one-step errors (the sensitivity system).

The predictor of :mod:`~stageid.closedloop.innovation_pem` is ``x^(t+1) = A x^ + B u + b0 + K e``,
``e = y - C x^ - D u - d0``.  Differentiating it along a parameter direction gives a system of the
same dynamics ``A~ = A - K C`` (Ljung, System Identification, 2nd ed., sec. 10.3):

    dx(t+1) = A~ dx + dA x^ + dB u + db0 + dK e - K (dC x^ + dD u + dd0),
    de      = -C dx - (dC x^ + dD u + dd0),                                  dx(0) = 0.

Every parameter's state input is a fixed vector times one of the signals ``s`` in
``[x^, u, 1, e]``, so all sensitivities follow from the filtered signals
``F_k(s)(t) = sum_{tau >= 1} lambda_k^(tau - 1) s(t - tau)`` over the eigenvalues ``lambda_k`` of
``A~ = V diag(lambda) V^-1``: the response of ``-C dx`` to a state input ``b s(t)`` is
``-(C V) diag(F(s)(t)) V^-1 b``.  This replaces one predictor simulation per parameter (forward
differences) by ``n`` first-order filters and two matrix products.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from ..models import StateSpaceModel
from .predictor_subspace import InnovationMatrices

__all__ = ["predictor_model", "predictor_signals", "error_sensitivity", "n_parameters"]

#: Above this condition number of the eigenvector basis of ``A - K C`` the modal route is not
#: trusted (a nearly defective predictor) and the caller falls back to finite differences.
MAX_BASIS_CONDITION = 1e8


def n_parameters(n: int, m: int, p: int, feedthrough: bool) -> int:
    """Length of ``theta = [vec A, vec B, vec C, vec K (, vec D), b0, d0]``."""
    return n * n + n * m + p * n + n * p + (p * m if feedthrough else 0) + n + p


def predictor_model(mats: InnovationMatrices, states: bool = False) -> StateSpaceModel:
    """The predictor as an LTI system from ``z = [u, 1, y]`` to ``e`` (or to ``x^`` when ``states``)."""
    A, B, C, D, K = mats.A, mats.B, mats.C, mats.D, mats.K
    n, p = A.shape[0], C.shape[0]
    b0 = np.zeros(n) if mats.state_offset is None else mats.state_offset
    d0 = np.zeros(p) if mats.output_offset is None else mats.output_offset
    Bp = np.hstack([B - K @ D, (b0 - K @ d0)[:, None], K])
    if states:
        return StateSpaceModel(A - K @ C, Bp, np.eye(n), np.zeros((n, Bp.shape[1])), dt=1.0)
    return StateSpaceModel(A - K @ C, Bp, -C, np.hstack([-D, -d0[:, None], np.eye(p)]), dt=1.0)


def predictor_signals(
    mats: InnovationMatrices, z: np.ndarray, x0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The predictor's states ``x^(t)`` and errors ``e(t)`` from ``x0`` (rest by default) for ``z = [u, 1, y]``.

    Returns ndarrays of shape (N, n) and (N, p).
    """
    X = predictor_model(mats, states=True).simulate(z, x0=x0)
    p = mats.C.shape[0]
    d0 = np.zeros(p) if mats.output_offset is None else mats.output_offset
    E = z @ np.hstack([-mats.D, -d0[:, None], np.eye(p)]).T - X @ mats.C.T
    return X, E


def _filtered(lam: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``F[k, t, s] = sum_{tau >= 1} lam_k^(tau - 1) S(t - tau, s)``, shape (n, N, n_signals), complex."""
    F = np.empty((lam.size, *S.shape), complex)
    for k, lk in enumerate(lam):
        F[k] = lfilter([0.0, 1.0], [1.0, -lk], S, axis=0)
    return F


def error_sensitivity(
    mats: InnovationMatrices, z: np.ndarray, feedthrough: bool, x0: np.ndarray | None = None
) -> np.ndarray | None:
    """``d e(t) / d theta`` of the predictor run from ``x0`` (held fixed), shape (N, p, n_theta), ``theta`` as packed.

    Returns None when ``A - K C`` has no well-conditioned eigenvector basis (then the modal
    filters would lose the digits the optimiser needs).
    """
    A, C, K = mats.A, mats.C, mats.K
    n, m, p = A.shape[0], mats.B.shape[1], C.shape[0]
    N = z.shape[0]
    lam, V = np.linalg.eig(A - K @ C)
    if n and np.linalg.cond(V) > MAX_BASIS_CONDITION:
        return None
    X, E = predictor_signals(mats, z, x0)
    S = np.hstack([X, z[:, : m + 1], E])  # the signals that drive the state: x^, u, 1, e (z's column m is 1)
    # a conjugate pair's two terms are each other's conjugates (real signals): keep one, count it twice
    keep = lam.imag >= 0
    CV = (C @ V)[:, keep] * np.where(lam.imag > 0, 2.0, 1.0)[keep]
    Vinv = np.linalg.inv(V)[keep]
    F = _filtered(lam[keep], S).reshape(CV.shape[1], -1)
    # T[o, i, t, s]: output o of C dx for the state input e_i s(t); TK the same for the state input K_i s(t)
    T = ((CV[:, None, :] * Vinv.T[None, :, :]).reshape(p * n, -1) @ F).real.reshape(p, n, N, -1)
    KV = Vinv @ K
    TK = ((CV[:, None, :] * KV.T[None, :, :]).reshape(p * p, -1) @ F).real.reshape(p, p, N, -1)
    x_, u_, one, e_ = slice(0, n), slice(n, n + m), slice(n + m, n + m + 1), slice(n + m + 1, n + m + 1 + p)
    J = np.empty((N, p, n_parameters(n, m, p, feedthrough)))
    blocks = [
        (-T[:, :, :, x_], None),  # A[i, j]: state input e_i x^_j
        (-T[:, :, :, u_], None),  # B[i, j]: e_i u_j
        (TK[:, :, :, x_], X),  # C[i, j]: -K_i x^_j into the state, -x^_j into e_i
        (-T[:, :, :, e_], None),  # K[i, j]: e_i e_j
        *([(TK[:, :, :, u_], z[:, :m])] if feedthrough else []),  # D[i, j]: like C with u_j
        (-T[:, :, :, one], None),  # b0[i]
        (TK[:, :, :, one], z[:, m : m + 1]),  # d0[i]
    ]
    start = 0
    for block, direct in blocks:
        _, rows, _, cols = block.shape
        view = J[:, :, start : start + rows * cols].reshape(N, p, rows, cols)
        view[...] = np.moveaxis(block, 2, 0)
        for o in range(p if direct is not None else 0):
            view[:, o, o, :] -= direct  # the direct term -[o == i] s(t) of dC, dD, dd0
        start += rows * cols
    return J
