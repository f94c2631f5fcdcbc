"""The zero-order-hold equivalent of a continuous SISO transfer function, and its derivatives.

The reduced fits (:mod:`~stageid.closedloop.reduction`) compare a continuous ``P_r = num / den``
with the sampled plant through ``ZOH{P_r}(z)`` at ``z = exp(j w dt)``; they evaluate it for every
residual, so the realisation is built directly (:func:`controller_canonical`) and the hold's
``expm`` differentiated exactly (:func:`zoh_derivatives`) for an analytic Jacobian.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss

__all__ = ["zoh_response", "zoh_at", "zoh_derivatives", "controller_canonical", "trim_leading"]


def zoh_response(num: np.ndarray, den: np.ndarray, dt: float, freqs_hz: np.ndarray) -> np.ndarray:
    """Frequency response of the ZOH equivalent of the continuous ``num/den`` at ``freqs_hz``.

    Computed exactly from ``expm`` of the controllable-canonical realisation (no
    ``(z - e^{p dt})`` partial fractions, so repeated poles are fine).
    """
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    return zoh_at(num, den, dt, np.exp(2j * np.pi * np.asarray(freqs_hz, dtype=float) * dt))


def zoh_at(num: np.ndarray, den: np.ndarray, dt: float, z: np.ndarray) -> np.ndarray:
    """:func:`zoh_response` at given points ``z = exp(j 2 pi f dt)`` (1-D float ``num``, ``den``):
    the reduced fits evaluate it for every residual on one grid."""
    num_t, den_t = trim_leading(num), trim_leading(den)
    if den_t.size == 1 and num_t.size <= 1:  # a static gain: tf2ss would give it one state at z = 1
        return np.full(z.shape, complex(num_t.sum() / den_t[0]))
    A, B, C, D = controller_canonical(num, den)
    n = A.shape[0]
    blk = np.zeros((n + 1, n + 1))
    blk[:n, :n] = A * dt
    blk[:n, n:] = B * dt
    E = sla.expm(blk)
    Ad, Bd = E[:n, :n], E[:n, n:]
    M = z[:, None, None] * np.eye(n)[None] - Ad[None]
    try:
        X = np.linalg.solve(M, np.broadcast_to(Bd, (z.size, n, 1)))
    except np.linalg.LinAlgError:
        # a point that is a pole, or a pole so far right that its hold overflows: infinite there
        # (a trial step of the reduced fits reaches this; their optimiser then shortens the step)
        return np.array([_solve_or_inf(Mk, Bd, C, D[0, 0]) for Mk in M])
    return (C[None] @ X)[:, 0, 0] + D[0, 0]


def _solve_or_inf(M: np.ndarray, Bd: np.ndarray, C: np.ndarray, d: float) -> complex:
    try:
        return complex((C @ np.linalg.solve(M, Bd))[0, 0] + d)
    except np.linalg.LinAlgError:
        return complex(np.inf, np.inf)


def zoh_derivatives(num: np.ndarray, den: np.ndarray, dt: float, z: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(H, dH/dnum, dH/dden[1:])`` of the ZOH equivalent of ``num / den`` (monic ``den``) at ``z``.

    ``dH/dnum`` has a column per coefficient of ``num`` padded to ``den``'s length.  The hold's
    ``expm`` is differentiated exactly (its Frechet derivative), so the fits need no differences.
    """
    n = den.size - 1
    A, _, C, D = controller_canonical(num, den)  # the realisation zoh_at differentiates
    C, d0 = C[0], D[0, 0]
    # expm of [[K, K_1 .. K_n], [0, K, 0 ..], ..] (K the hold's block, K_i = dK / d den_i): its
    # first block row holds expm(K) and every Frechet derivative L(K, K_i) (Van Loan 1978)
    m = n + 1
    big = np.zeros(((n + 1) * m, (n + 1) * m))
    for k in range(n + 1):
        big[k * m : k * m + n, k * m : k * m + n] = A * dt
        big[k * m, k * m + n] = dt
    for i in range(n):
        big[0, (i + 1) * m + i] = -dt
    E = sla.expm(big)[:m]
    Ad, Bd = E[:n, :n], E[:n, n]
    M = z[:, None, None] * np.eye(n)[None] - Ad[None]
    X = np.linalg.solve(M, np.broadcast_to(Bd[:, None], (z.size, n, 1)))[:, :, 0]  # (zI - Ad)^-1 Bd
    V = np.linalg.solve(np.swapaxes(M, 1, 2), np.broadcast_to(C[:, None], (z.size, n, 1)))[:, :, 0]
    H = X @ C + d0
    d_num = np.empty((z.size, n + 1), dtype=complex)
    d_num[:, 0] = 1.0 - X @ den[1:]
    d_num[:, 1:] = X
    d_den = np.empty((z.size, n), dtype=complex)
    for i in range(n):
        dE = E[:, (i + 1) * m : (i + 2) * m]
        d_den[:, i] = -d0 * X[:, i] + np.einsum("kj,kj->k", V, X @ dE[:n, :n].T + dE[:n, n])
    return H, d_num, d_den


def trim_leading(p: np.ndarray) -> np.ndarray:
    """``np.trim_zeros(p, "f")`` for a 1-D array (without its generic, slower machinery)."""
    nz = np.flatnonzero(p)
    return p[nz[0] :] if nz.size else p[:0]


def controller_canonical(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, ...]:
    """``scipy.signal.tf2ss(num, den)`` for a proper SISO ``num/den`` (the same numbers, without its
    argument handling: the reduced fits call it for every residual).  Cases where ``tf2ss`` would
    trim or warn about tiny leading numerator coefficients, or refuse, go to ``tf2ss`` itself."""
    den_t = trim_leading(den)
    numn, dn = num / den_t[0], den_t / den_t[0]
    K = dn.size
    if numn.size == 0 or abs(numn[0]) <= 1e-14 or numn.size > K or K == 1:
        return ss.tf2ss(num, den)
    nump = np.concatenate([np.zeros(K - numn.size), numn])
    A = np.zeros((K - 1, K - 1))
    A[0] = -dn[1:]
    A[1:, :-1] = np.eye(K - 2)
    B = np.zeros((K - 1, 1))
    B[0, 0] = 1.0
    return A, B, (nump[1:] - nump[0] * dn[1:])[None, :], np.array([[nump[0]]])
