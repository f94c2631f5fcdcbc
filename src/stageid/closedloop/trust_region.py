"""Trust-region nonlinear least squares for the prediction-error fits (Moré 1977; SciPy's ``trf``).

The same iteration as :func:`scipy.optimize.least_squares` with ``method="trf"``,
``x_scale="jac"``, no bounds and the exact trust-region solver: the Levenberg-Marquardt
step of Moré (1977) from one SVD of the scaled Jacobian per iteration.  The prediction-error
Jacobians are tall (``10 000 x 2n``); SciPy takes the SVD of the whole matrix (and forms its
``U``), here one Householder QR of ``[J_h | f]`` reduces it to the ``(n + 1) x (n + 1)``
triangle first and the SVD is that of ``R`` (the same singular values and right vectors,
``U^T f`` from ``Q^T f``).  The trust-region logic, radius updates and stopping tests are
SciPy's, so the iterates agree with ``least_squares`` to rounding.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.linalg import norm
from scipy.linalg import lapack

__all__ = ["TrustRegionResult", "trust_region_lsq", "lm_step", "update_radius", "termination"]

EPS = np.finfo(float).eps


@dataclass(frozen=True)
class TrustRegionResult:
    """``x`` at the end, residuals ``fun`` there, evaluations ``nfev`` and SciPy's ``status``.

    ``status``: 0 stopped on ``max_nfev``; 1 ``gtol``; 2 ``ftol``; 3 ``xtol``; 4 both ``ftol``
    and ``xtol`` (as :func:`scipy.optimize.least_squares`).
    """

    x: np.ndarray
    fun: np.ndarray
    nfev: int
    status: int


def _reduced_svd(J: np.ndarray, d: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(uf, s, V, R)`` of ``J_h = J diag(d)``: ``U^T f``, singular values, right vectors and a triangle.

    ``R`` satisfies ``|J_h p| = |R p|`` for every ``p``.
    """
    m, n = J.shape
    if m <= n + 1:  # wide or square: the plain SVD, as SciPy
        J_h = J * d
        U, s, Vt = np.linalg.svd(J_h, full_matrices=False)
        return U.T @ f, s, Vt.T, J_h
    W = np.empty((m, n + 1), order="F")
    np.multiply(J, d, out=W[:, :n])
    W[:, n] = f
    qr = lapack.dgeqrf(W, overwrite_a=1)[0]
    R = np.triu(qr[:n, :n])
    Ur, s, Vt = np.linalg.svd(R)
    return Ur.T @ qr[:n, n], s, Vt.T, R


def lm_step(n: int, m: int, uf, s, V, Delta: float, initial_alpha: float | None = None, rtol=0.01, max_iter=10):
    """Moré's trust-region step from the SVD of the Jacobian: ``(p, alpha)``.

    A transcription of SciPy's ``solve_lsq_trust_region`` (``p`` minimises ``|J p + f|`` subject to
    ``|p| <= Delta``; ``alpha`` is the Levenberg-Marquardt parameter).
    """

    def phi_and_derivative(alpha):
        denom = s**2 + alpha
        p_norm = norm(suf / denom)
        return p_norm - Delta, -np.sum(suf**2 / denom**3) / p_norm

    suf = s * uf
    full_rank = bool(s[-1] > EPS * m * s[0]) if m >= n else False
    if full_rank:
        p = -V.dot(uf / s)
        if norm(p) <= Delta:
            return p, 0.0
    alpha_upper = norm(suf) / Delta
    if full_rank:
        phi, phi_prime = phi_and_derivative(0.0)
        alpha_lower = -phi / phi_prime
    else:
        alpha_lower = 0.0
    if initial_alpha is None or not full_rank and initial_alpha == 0:
        alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
    else:
        alpha = initial_alpha
    for _ in range(max_iter):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, (alpha_lower * alpha_upper) ** 0.5)
        phi, phi_prime = phi_and_derivative(alpha)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + Delta) * ratio / Delta
        if np.abs(phi) < rtol * Delta:
            break
    p = -V.dot(suf / (s**2 + alpha))
    p *= Delta / norm(p)  # exactly on the boundary, as SciPy
    return p, alpha


def update_radius(Delta: float, actual: float, predicted: float, step_norm: float, bound_hit: bool):
    """``(Delta, ratio)``: shrink to a quarter of the step when the model predicted badly, double on a good boundary step."""
    if predicted > 0:
        ratio = actual / predicted
    elif predicted == actual == 0:
        ratio = 1
    else:
        ratio = 0
    if ratio < 0.25:
        Delta = 0.25 * step_norm
    elif ratio > 0.75 and bound_hit:
        Delta *= 2.0
    return Delta, ratio


def termination(dF: float, F: float, dx_norm: float, x_norm: float, ratio: float, ftol: float, xtol: float):
    """SciPy's stopping test: 4 both, 2 ``ftol``, 3 ``xtol``, else None."""
    ftol_ok = dF < ftol * F and ratio > 0.25
    xtol_ok = dx_norm < xtol * (xtol + x_norm)
    if ftol_ok and xtol_ok:
        return 4
    if ftol_ok:
        return 2
    if xtol_ok:
        return 3
    return None


def trust_region_lsq(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    max_nfev: int,
    ftol: float = 1e-12,
    xtol: float = 1e-12,
    gtol: float = 1e-12,
) -> TrustRegionResult:
    """Minimise ``|fun(x)|^2 / 2`` from ``x0``: SciPy's ``trf`` (no bounds, ``x_scale="jac"``) on a QR-reduced Jacobian.

    Raises
    ------
    ValueError
        When the residuals at ``x0`` are not finite (as :func:`scipy.optimize.least_squares`).
    """
    x = np.array(x0, dtype=float)
    f = fun(x)
    if not np.all(np.isfinite(f)):
        raise ValueError("Residuals are not finite in the initial point.")
    nfev = 1
    J = jac(x)
    m, n = J.shape
    cost = 0.5 * np.dot(f, f)
    g = J.T.dot(f)
    scale_inv = np.sum(J**2, axis=0) ** 0.5
    scale_inv[scale_inv == 0] = 1
    scale = 1 / scale_inv
    Delta = norm(x * scale_inv)
    if Delta == 0:
        Delta = 1.0
    alpha = 0.0
    status = None
    while True:
        if norm(g, ord=np.inf) < gtol:
            status = 1
        if status is not None or nfev == max_nfev:
            break
        d = scale
        g_h = d * g
        uf, s, V, R = _reduced_svd(J, d, f)
        actual = -1
        while actual <= 0 and nfev < max_nfev:
            step_h, alpha = lm_step(n, m, uf, s, V, Delta, initial_alpha=alpha)
            Js = R.dot(step_h)
            predicted = -(0.5 * np.dot(Js, Js) + np.dot(g_h, step_h))
            step = d * step_h
            x_new = x + step
            f_new = fun(x_new)
            nfev += 1
            step_h_norm = norm(step_h)
            if not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * np.dot(f_new, f_new)
            actual = cost - cost_new
            Delta_new, ratio = update_radius(Delta, actual, predicted, step_h_norm, step_h_norm > 0.95 * Delta)
            status = termination(actual, cost, norm(step), norm(x), ratio, ftol, xtol)
            if status is not None:
                break
            alpha *= Delta / Delta_new
            Delta = Delta_new
        if actual > 0:
            x, f, cost = x_new, f_new, cost_new
            J = jac(x)
            g = J.T.dot(f)
            scale_inv = np.maximum(np.sum(J**2, axis=0) ** 0.5, scale_inv)
            scale = 1 / scale_inv
    return TrustRegionResult(x, f, nfev, 0 if status is None else status)
