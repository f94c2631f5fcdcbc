"""The zero-order-hold equivalent of a continuous SISO transfer function, and its derivatives.

The reduced fits (:mod:`~stageid.closedloop.reduction`) compare a continuous ``P_r = num / den``
with the sampled plant through ``ZOH{P_r}(z)`` at ``z = exp(j w dt)``; they evaluate it for every
residual, so the realisation is the cheap controllable canonical form of
:func:`~stageid.models.conversions.tf2ss_siso` and the hold's ``expm`` is differentiated exactly
(:func:`zoh_derivatives`) for an analytic Jacobian.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from ..models.conversions import strip_leading_zeros, tf2ss_siso

__all__ = ["zoh_response", "zoh_at", "zoh_derivatives"]


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
    num_t, den_t = strip_leading_zeros(num), strip_leading_zeros(den)
    if den_t.size == 1 and num_t.size <= 1:  # a static gain: no state, no hold
        return np.full(z.shape, complex(num_t[0] / den_t[0]))
    A, B, C, D = tf2ss_siso(num, den, keep_states=True)
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
    A, _, C, D = tf2ss_siso(num, den, keep_states=True)  # the realisation zoh_at differentiates
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
