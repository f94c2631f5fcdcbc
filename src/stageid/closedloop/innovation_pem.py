"""Prediction-error refinement of the innovation form and its parameter covariance.

The one-step predictor of ``x(t+1) = A x + B u + K e``, ``y = C x + D u + e`` is
``x^(t+1) = (A - K C) x^ + (B - K D) u + K y``, ``e = y - C x^ - D u`` (Ljung, System
Identification, 2nd ed., eq. 4.91).  It is simulated as an LTI system from ``[u; y]`` to
``e``, so it stays bounded for an unstable ``A`` as long as ``A - K C`` is stable, and the
cost ``sum e' Lambda^-1 e`` is minimised over the full matrices by ``scipy.optimize.least_squares``
(the similarity freedom leaves ``n^2`` flat directions, which the trust region tolerates and the
covariance removes by a pseudo-inverse).  The Jacobian is the sensitivity system's
(:mod:`~stageid.closedloop.innovation_jacobian`), forward differences only where ``A - K C`` has
no usable eigenvector basis.  Bands on poles and on the frequency response follow by the delta
method from the Jacobian at the optimum.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import IdentificationError
from .innovation_jacobian import error_sensitivity, n_parameters, predictor_model
from .predictor_subspace import InnovationMatrices

__all__ = [
    "PemResult",
    "PemFit",
    "predictor_residuals",
    "refine",
    "pole_std",
    "response_std",
    "pack",
    "unpack",
    "transient_length",
]


def pack(m: InnovationMatrices, feedthrough: bool) -> np.ndarray:
    """``theta = [vec A, vec B, vec C, vec K (, vec D), b0, d0]`` (row-major; zero offsets when absent)."""
    n, p = m.A.shape[0], m.C.shape[0]
    b0 = np.zeros(n) if m.state_offset is None else m.state_offset
    d0 = np.zeros(p) if m.output_offset is None else m.output_offset
    parts = [m.A, m.B, m.C, m.K] + ([m.D] if feedthrough else []) + [b0, d0]
    return np.concatenate([x.ravel() for x in parts])


def unpack(theta: np.ndarray, n: int, m: int, p: int, feedthrough: bool, noise_cov: np.ndarray) -> InnovationMatrices:
    """Inverse of :func:`pack` (``D = 0`` without feedthrough)."""
    sizes = [n * n, n * m, p * n, n * p, p * m if feedthrough else 0, n]
    cut = np.cumsum(sizes)
    A = theta[: cut[0]].reshape(n, n)
    B = theta[cut[0] : cut[1]].reshape(n, m)
    C = theta[cut[1] : cut[2]].reshape(p, n)
    K = theta[cut[2] : cut[3]].reshape(n, p)
    D = theta[cut[3] : cut[4]].reshape(p, m) if feedthrough else np.zeros((p, m))
    return InnovationMatrices(A, B, C, D, K, noise_cov, theta[cut[4] : cut[5]], theta[cut[5] :])


def predictor_residuals(m: InnovationMatrices, records: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray]:
    """One-step prediction errors ``e(t)`` per record, the predictor's initial state fitted.

    From rest the predictor's transient would colour the first hundreds of samples (its slowest
    mode mirrors an unstable pole); the initial state enters ``e`` linearly, ``e = e_0 - O x0``
    with ``O(t) = C (A - K C)^t``, so it is fitted by least squares over the transient
    (:func:`initial_state`) and the predictor is run from it.
    """
    return stacked_residuals(m, [np.hstack([u, np.ones((u.shape[0], 1)), y]) for u, y in records])


def stacked_residuals(m: InnovationMatrices, stacked: Sequence[np.ndarray]) -> list[np.ndarray]:
    """:func:`predictor_residuals` on records already stacked as ``[u, 1, y]`` (the optimiser's loop)."""
    pred = predictor_model(m)
    out = []
    for z in stacked:
        x0 = initial_state(m, pred.simulate(z))
        out.append(pred.simulate(z) if x0 is None else pred.simulate(z, x0=x0))
    return out


def initial_state(m: InnovationMatrices, e_rest: np.ndarray) -> np.ndarray | None:
    """The predictor's initial state fitted to the errors ``e_rest`` it makes from rest, over its transient.

    None without states.  ``e = e_rest - O x0``, ``O(t) = C (A - K C)^t``, by least squares over
    the samples until the slowest predictor mode has decayed to 1e-3.
    """
    p, n = m.C.shape[0], m.A.shape[0]
    L = transient_length(m, 1, e_rest.shape[0]) if n else 0
    if not L:
        return None
    O = free_response(m.C, m.A - m.K @ m.C, L).reshape(L * p, n)
    return np.linalg.lstsq(O, e_rest[:L].ravel(), rcond=None)[0]


def project_initial_state(m: InnovationMatrices, J: np.ndarray, z: np.ndarray, x0: np.ndarray | None) -> None:
    """Add to the sensitivities ``J`` (shape (N, p, n_theta), ``x0`` held), in place, the response of ``x0``'s fit.

    ``x0 = O_L^+ e_rest`` moves with ``theta``: ``dx0 = O_L^+ J_L + (O_L' O_L)^+ dO_L' r_L`` (Golub
    and Pereyra's variable projection, ``r`` the errors from ``x0``); ``-O dx0`` is added until
    ``O`` has decayed to 1e-12.  ``dO`` is the sensitivity of the free response from each unit state.
    """
    p, n = m.C.shape[0], m.A.shape[0]
    L = transient_length(m, 1, J.shape[0]) if n else 0
    if not L or x0 is None:
        return
    span = min(4 * L, J.shape[0])
    O = free_response(m.C, m.A - m.K @ m.C, span).reshape(span * p, n)
    P = np.linalg.pinv(O[: L * p], rcond=np.finfo(float).eps * L * p)
    r = predictor_model(m).simulate(z[:L], x0=x0)
    feedthrough = J.shape[2] > n_parameters(n, m.B.shape[1], p, False)
    rest = np.zeros((L, z.shape[1]))
    g = np.stack([error_sensitivity(m, rest, feedthrough, unit) for unit in np.eye(n)])  # -dO e_j, (n, L, p, k)
    g = -np.einsum("jtok,to->jk", g, r)
    dx0 = P @ J[:L].reshape(L * p, -1) + P @ (P.T @ g)
    J[:span] -= (O @ dx0).reshape(J[:span].shape)


def free_response(C: np.ndarray, A: np.ndarray, length: int) -> np.ndarray:
    """``C A^t`` for ``t = 0 .. length - 1``, shape (length, p, n), by the eigenvalues of ``A``.

    A defective ``A`` (no eigenvector basis) falls back to repeated products.
    """
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) < 1e8:
        powers = lam[None, :] ** np.arange(length)[:, None]
        out = np.einsum("pk,tk,kn->tpn", C @ V, powers, np.linalg.inv(V))
        return out.real
    out = np.empty((length, C.shape[0], A.shape[0]))
    CAk = C.copy()
    for t in range(length):
        out[t] = CAk
        CAk = CAk @ A
    return out


@dataclass(frozen=True)
class PemResult:
    """Refined matrices, the covariance of ``theta`` (None when not computed), and the optimiser's account."""

    matrices: InnovationMatrices
    covariance: np.ndarray | None
    n_effective: int
    nfev: int
    converged: bool
    cost_start: float
    cost: float
    burn: int


PemFit = PemResult  # its former name


def _whitener(noise_cov: np.ndarray) -> np.ndarray:
    """``W`` with ``W Lambda W' = I`` (``Lambda`` regularised for a silent channel)."""
    lam = noise_cov + 1e-12 * np.trace(noise_cov) * np.eye(noise_cov.shape[0])
    return np.linalg.inv(np.linalg.cholesky(lam))


def refine(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    start: InnovationMatrices,
    feedthrough: bool,
    burn: int,
    max_nfev: int,
) -> PemResult:
    """Minimise the weighted one-step prediction error from ``start`` (see the module notes).

    The predictor's initial state is fitted in every evaluation (:func:`predictor_residuals`);
    the first ``burn`` samples of each record, or more until the start's slowest predictor mode
    has decayed to 1e-3, are still left out of the cost, where that fit leans on them.  The
    trust region stops when the cost changes by less than 1e-7 relative, a small fraction of one
    unit of chi-square at these record lengths.  Raises :class:`IdentificationError` when the
    start's predictor is unstable.
    """
    from scipy.optimize import least_squares

    n, m, p = start.A.shape[0], start.B.shape[1], start.C.shape[0]
    if n and np.max(np.abs(start.predictor_poles)) >= 1:
        raise IdentificationError("the subspace start has an unstable predictor A - K C; try another order or horizon.")
    W = _whitener(start.noise_cov)
    burn = transient_length(start, burn, min(u.shape[0] for u, _ in records) // 4)
    stacked = [np.hstack([u, np.ones((u.shape[0], 1)), y]) for u, y in records]

    def cost_vector(theta: np.ndarray) -> np.ndarray:
        mats = unpack(theta, n, m, p, feedthrough, start.noise_cov)
        if n and np.max(np.abs(mats.predictor_poles)) >= 0.9999:
            return fallback  # outside the stable predictors: a wall the trust region steps back from
        E = stacked_residuals(mats, stacked)
        return np.concatenate([(e[burn:] @ W.T).ravel() for e in E])

    theta0 = pack(start, feedthrough)
    fallback = np.zeros(0)
    r0 = cost_vector(theta0)
    fallback = 1e3 * (np.abs(r0) + 1.0)

    def jacobian(theta: np.ndarray) -> np.ndarray:
        J = weighted_jacobian(unpack(theta, n, m, p, feedthrough, start.noise_cov), stacked, W, burn, feedthrough)
        return difference_jacobian(cost_vector, theta, fallback) if J is None else J

    sol = least_squares(
        cost_vector, theta0, jac=jacobian, method="trf", x_scale="jac", max_nfev=max_nfev, ftol=1e-7, tr_solver="lsmr"
    )
    E = predictor_residuals(unpack(sol.x, n, m, p, feedthrough, start.noise_cov), records)
    cov, k_eff = _covariance(jacobian(sol.x), sol.fun)
    pooled = np.vstack([e[burn:] for e in E])
    lam = pooled.T @ pooled / pooled.shape[0]
    mats = unpack(sol.x, n, m, p, feedthrough, lam)
    return PemResult(
        mats, cov, k_eff, int(sol.nfev), bool(sol.status > 0), float(r0 @ r0), float(sol.fun @ sol.fun), burn
    )


def weighted_jacobian(
    mats: InnovationMatrices, stacked: Sequence[np.ndarray], W: np.ndarray, burn: int, feedthrough: bool
) -> np.ndarray | None:
    """The Jacobian of :func:`refine`'s cost vector from the sensitivity system, or None without a modal basis.

    Rows as the cost vector: per record ``W e(t)`` for ``t >= burn``, the initial state's fit
    projected out (:func:`project_initial_state`); columns ``theta`` as :func:`pack` orders it.
    """
    blocks = []
    pred = predictor_model(mats)
    for z in stacked:
        x0 = initial_state(mats, pred.simulate(z))
        J = error_sensitivity(mats, z, feedthrough, x0)
        if J is None:
            return None
        project_initial_state(mats, J, z, x0)
        blocks.append(np.matmul(W, J[burn:]).reshape(-1, J.shape[2]))
    return np.vstack(blocks)


def difference_jacobian(cost_vector, theta: np.ndarray, wall: np.ndarray) -> np.ndarray:
    """Forward differences of ``cost_vector``, stepping backwards where a step hits ``wall`` (an unstable predictor)."""
    f0 = cost_vector(theta)
    J = np.empty((f0.size, theta.size))
    for k in range(theta.size):
        h = 1e-6 * max(abs(theta[k]), 1e-2)
        t = theta.copy()
        t[k] += h
        f1 = cost_vector(t)
        if f1 is wall:
            t[k] -= 2 * h
            f1, h = cost_vector(t), -h
        J[:, k] = (f1 - f0) / h
    return J


def transient_length(m: InnovationMatrices, at_least: int, at_most: int) -> int:
    """Samples until the predictor's slowest mode decays to 1e-3, within ``[at_least, at_most]``."""
    rho = float(np.max(np.abs(m.predictor_poles))) if m.A.size else 0.0
    n = int(np.ceil(np.log(1e-3) / np.log(rho))) if 0 < rho < 1 else at_least
    return int(min(max(n, at_least), max(at_most, at_least)))


def _covariance(jac: np.ndarray, fun: np.ndarray) -> tuple[np.ndarray, int]:
    """``s^2 (J'J)^+`` over the identifiable directions (the similarity directions dropped)."""
    JtJ = jac.T @ jac
    w, V = np.linalg.eigh(JtJ)
    keep = w > 1e-9 * w.max()
    k_eff = int(keep.sum())
    s2 = float(fun @ fun) / max(fun.size - k_eff, 1)
    return s2 * (V[:, keep] / w[keep]) @ V[:, keep].T, k_eff


def pole_std(mats: InnovationMatrices, cov: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Continuous poles ``ln(z) / dt`` of ``A`` (rad/s) and ``sqrt(E|s_est - s|^2)`` of each.

    First-order eigenvalue perturbation ``dz = w^H dA v / w^H v`` (only ``A`` moves the poles).
    """
    z, V = np.linalg.eig(mats.A)
    Wl = np.linalg.inv(V)  # rows are the left eigenvectors, scaled so that Wl V = I
    n = z.size
    s = np.log(z.astype(complex)) / dt
    std = np.empty(n)
    P = cov[: n * n, : n * n]
    for k in range(n):
        g = np.outer(Wl[k], V[:, k]).ravel() / (z[k] * dt)  # d s_k / d vec(A), row-major
        std[k] = np.sqrt(max(float(g.real @ P @ g.real + g.imag @ P @ g.imag), 0.0))
    return s, std


def response_std(mats: InnovationMatrices, cov: np.ndarray, freqs_hz: np.ndarray, dt: float, feedthrough: bool):
    """The plant response ``C (zI - A)^-1 B + D`` at ``freqs_hz`` and its delta-method std per entry."""
    A, B, C = mats.A, mats.B, mats.C
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    cut = np.cumsum([n * n, n * m, p * n, n * p])
    out = np.empty((freqs_hz.size, p, m), complex)
    std = np.empty((freqs_hz.size, p, m))
    for f_i, f in enumerate(freqs_hz):
        R = np.linalg.inv(np.exp(2j * np.pi * f * dt) * np.eye(n) - A)
        CR, RB = C @ R, R @ B
        out[f_i] = C @ RB + mats.D
        g = np.zeros((p, m, cov.shape[0]), complex)
        g[:, :, : cut[0]] = np.einsum("oi,jq->oqij", CR, RB).reshape(p, m, n * n)
        g[:, :, cut[0] : cut[1]] = np.einsum("oi,qj->oqij", CR, np.eye(m)).reshape(p, m, n * m)
        g[:, :, cut[1] : cut[2]] = _dC(RB, p, m, n)
        if feedthrough:
            g[:, :, cut[3] : cut[3] + p * m] = np.einsum("oa,qb->oqab", np.eye(p), np.eye(m)).reshape(p, m, p * m)
        var = np.einsum("oqk,kl,oql->oq", g.real, cov, g.real) + np.einsum("oqk,kl,oql->oq", g.imag, cov, g.imag)
        std[f_i] = np.sqrt(np.maximum(var, 0.0))
    return out, std


def _dC(RB: np.ndarray, p: int, m: int, n: int) -> np.ndarray:
    """``d G[o, q] / d C[a, b] = [o == a] (R B)[b, q]``, flattened over ``(a, b)`` row-major."""
    g = np.zeros((p, m, p, n), complex)
    for o in range(p):
        g[o, :, o, :] = RB.T
    return g.reshape(p, m, p * n)
