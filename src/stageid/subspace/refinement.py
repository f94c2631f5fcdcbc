"""Output-error refinement of a realisation on the frequency response of eq. 9.

The last step of the frequency route of the realisation (see :mod:`.frequency_domain`):
Levenberg-Marquardt over all entries of ``A, B, C, D`` on
``sum_k ||C (z_k I - A)^-1 B + D - G_k||^2``, with the normal equations formed from the
product structure of the Jacobian, never the Jacobian itself.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["refine_frequency_fit", "fit_cost", "refinement_bytes", "REFINE_TOL", "MULTI_START_MISFIT"]

#: Relative cost decrease below which the refinement stops: later steps move the response far
#: less than its own uncertainty (measurements: ``benchmarks/RESULTS-subspace.md``).
REFINE_TOL = 3e-3
#: Relative misfit (cost over the response's energy) above which the refinement also runs from
#: the second start: the order cannot fit the system and a closer start need not lead to the
#: better optimum (misfits seen: ``benchmarks/RESULTS-subspace.md``).
MULTI_START_MISFIT = 1e-3


def refinement_bytes(order: int, n_inputs: int, n_outputs: int, n_frequencies: int) -> float:
    """Memory the refinement of an ``order``-state realisation takes: the normal-equation
    matrix over ``A, B, C, D`` (``P^2`` for ``P`` parameters) with the ``A`` block's product
    and its solver copy, and the ``(n_frequencies, n, n)`` complex resolvent products."""
    n, m, q = float(order), float(n_inputs), float(n_outputs)
    P = n * n + n * m + q * n + q * m
    return 8.0 * (3.0 * P * P + 2.0 * n**4) + 16.0 * 6.0 * n_frequencies * n * (n + m + q)


def _model_response(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    D: np.ndarray,
    zs: np.ndarray,
    eig: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``G = C R B + D`` with ``R = (zI - A)^-1``; also returns ``C R`` and ``R B``
    (``eig``: ``numpy.linalg.eig(A)`` when the caller has it already)."""
    lam, V = np.linalg.eig(A) if eig is None else eig
    Vi = np.linalg.inv(V)
    nz, q, n, m = zs.size, C.shape[0], A.shape[0], B.shape[1]
    inv = 1.0 / (zs[:, None] - lam[None, :])  # (nz, n)
    # V, Vi and Vi B are the same at every z: one product each over all z, not nz small ones
    CVi = ((C @ V)[None, :, :] * inv[:, None, :]).reshape(nz * q, n)  # rows (z, output)
    ViB = Vi @ B
    CR = (CVi @ Vi).reshape(nz, q, n)
    RB = (V @ (inv.T[:, :, None] * ViB[:, None, :]).reshape(n, nz * m)).reshape(n, nz, m)
    RB = np.ascontiguousarray(RB.transpose(1, 0, 2))  # (nz, n, m), laid out as the normal equations read it
    G = (CVi @ ViB).reshape(nz, q, m) + D[None]
    return G, CR, RB


def fit_cost(abcd: tuple[np.ndarray, ...], G: np.ndarray, zs: np.ndarray) -> float:
    """``sum |C (zI - A)^-1 B + D - G|^2`` over the frequencies (inf when not finite)."""
    try:
        c = float(np.sum(np.abs(_model_response(*abcd, zs)[0] - G) ** 2))
    except np.linalg.LinAlgError:
        return float("inf")
    return c if np.isfinite(c) else float("inf")


def _re_mm(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``Re(X @ Y)`` with two real products instead of a complex one."""
    out = X.real @ Y.real
    out -= X.imag @ Y.imag
    return out


@lru_cache(maxsize=8)
def _hermitian_plan(n: int) -> tuple[np.ndarray, ...]:
    """Index plan of :func:`_hermitian_block`: the ``i <= k`` and ``i < k`` pairs of an ``n x n``
    matrix, where each entry of the ``(i, j), (k, l)`` block reads its pair products, and the signs."""
    iu, ku = np.triu_indices(n)
    ia, ka = np.triu_indices(n, 1)
    sym = np.empty((n, n), dtype=np.intp)
    sym[iu, ku] = sym[ku, iu] = np.arange(iu.size)
    asym = np.zeros((n, n), dtype=np.intp)
    asym[ia, ka] = asym[ka, ia] = np.arange(ia.size)
    sign = np.zeros((n, n))
    sign[ia, ka], sign[ka, ia] = 1.0, -1.0
    idx_r = (sym[:, None, :, None] * iu.size + sym[None, :, None, :]).reshape(n * n, n * n)
    idx_i = (asym[:, None, :, None] * ia.size + asym[None, :, None, :]).reshape(n * n, n * n)
    signs = (sign[:, None, :, None] * sign[None, :, None, :]).reshape(n * n, n * n)
    return iu * n + ku, ia * n + ka, idx_r, idx_i, signs


def _hermitian_block(Ma: np.ndarray, Mb: np.ndarray) -> np.ndarray:
    """``X[(i, j), (k, l)] = Re sum_z Ma[z, i, k] Mb[z, j, l]`` for Hermitian ``Ma[z]`` and ``Mb[z]``.

    The real parts are symmetric and the imaginary parts antisymmetric in each pair, so the sum
    needs the ``i <= k`` (real) and ``i < k`` (imaginary) pairs only: about a quarter of the flops
    of the full product (the ``A`` block of the normal equations).
    """
    nz, n, _ = Ma.shape
    su, sa, idx_r, idx_i, signs = _hermitian_plan(n)
    Ma2, Mb2 = Ma.reshape(nz, n * n), Mb.reshape(nz, n * n)
    Kr = Ma2.real[:, su].T @ Mb2.real[:, su]
    Ki = Ma2.imag[:, sa].T @ Mb2.imag[:, sa]
    out = Kr.take(idx_r)
    if sa.size:  # no i < k pairs for one state
        out -= signs * Ki.take(idx_i)
    return out


def _normal_equations(
    a: np.ndarray, b: np.ndarray, e: np.ndarray, w: np.ndarray, feedthrough: bool
) -> tuple[np.ndarray, np.ndarray]:
    """``J^T J`` and ``J^T r`` of the frequency fit over ``vec(A), vec(B), vec(C), vec(D)``.

    Uses the product structure ``dG/dA_ij = (C R)[:, i] (R B)[j, :]`` so the Jacobian itself
    is never formed: every block is a weighted sum over frequencies of small outer products.
    ``a = C R`` (nz, q, n), ``b = R B`` (nz, n, m), ``e`` the residual (nz, q, m).  The blocks
    are written straight into one preallocated matrix (few large temporaries: see
    :func:`~stageid.subspace.hankel_toeplitz.lag_correlations` on why that matters).
    """
    nz, q, n = a.shape
    m = b.shape[2]
    nA, nB, nC, nD = n * n, n * m, q * n, (q * m if feedthrough else 0)
    iA, iB, iC, iD = 0, nA, nA + nB, nA + nB + nC
    P = iD + nD
    JtJ = np.empty((P, P))
    aw = a * w[:, None, None]
    caw = np.conj(aw).reshape(nz, q * n)  # (z, (r, i))
    cb = np.conj(b)
    Ma = np.matmul(np.conj(aw).transpose(0, 2, 1), a)  # weighted a^H a, (z, i, k)
    Mb = np.matmul(cb, b.transpose(0, 2, 1))  # conj(b) b^T, (z, j, l)
    Ma2 = Ma.reshape(nz, n * n)
    Mb2 = Mb.reshape(nz, n * n)
    cb2 = cb.reshape(nz, n * m)

    def put(r0: int, c0: int, blk: np.ndarray) -> None:
        JtJ[r0 : r0 + blk.shape[0], c0 : c0 + blk.shape[1]] = blk
        if r0 != c0:
            JtJ[c0 : c0 + blk.shape[1], r0 : r0 + blk.shape[0]] = blk.T

    # AA[i,j,k,l] = Re sum_z w Ma[i,k] Mb[j,l]
    JtJ[:nA, :nA] = _hermitian_block(Ma, Mb)
    put(iA, iB, _re_mm(Ma2.T, cb2).reshape(n, n, n, m).transpose(0, 2, 1, 3).reshape(nA, nB))
    put(iA, iC, _re_mm(caw.T, Mb2).reshape(q, n, n, n).transpose(1, 2, 0, 3).reshape(nA, nC))
    put(iB, iB, np.kron(Ma.sum(axis=0).real, np.eye(m)))
    put(iB, iC, _re_mm(caw.T, b.reshape(nz, n * m)).reshape(q, n, n, m).transpose(1, 3, 0, 2).reshape(nB, nC))
    put(iC, iC, np.kron(np.eye(q), (w @ Mb2).real.reshape(n, n)))
    ew = e * w[:, None, None]
    gA = np.matmul(np.matmul(np.conj(a).transpose(0, 2, 1), ew), cb.transpose(0, 2, 1)).sum(axis=0).real.reshape(-1)
    gB = np.matmul(np.conj(a).transpose(0, 2, 1), ew).sum(axis=0).real.reshape(-1)
    gC = np.matmul(ew, cb.transpose(0, 2, 1)).sum(axis=0).real.reshape(-1)
    grads = [gA, gB, gC]
    if feedthrough:
        put(iA, iD, _re_mm(caw.T, cb2).reshape(q, n, n, m).transpose(1, 2, 0, 3).reshape(nA, nD))
        sa = np.conj(aw).sum(axis=0).real  # (r, i)
        put(iB, iD, np.einsum("ri,cd->icrd", sa, np.eye(m)).reshape(nB, nD))
        sb = (w[:, None, None] * cb).sum(axis=0).real  # (i, c)
        put(iC, iD, np.einsum("rs,ic->risc", np.eye(q), sb).reshape(nC, nD))
        put(iD, iD, w.sum() * np.eye(nD))
        grads.append(ew.sum(axis=0).real.reshape(-1))
    return JtJ, np.concatenate(grads)


def _stepped(A, B, C, D, step: np.ndarray, feedthrough: bool) -> tuple[np.ndarray, ...]:
    """``A, B, C, D`` moved by ``step`` (their entries in that order; ``D`` only with feedthrough)."""
    n, m, q = A.shape[0], B.shape[1], C.shape[0]
    A1 = A + step[: n * n].reshape(n, n)
    B1 = B + step[n * n : n * n + n * m].reshape(n, m)
    C1 = C + step[n * n + n * m : n * n + n * m + q * n].reshape(q, n)
    D1 = D + step[n * n + n * m + q * n :].reshape(q, m) if feedthrough else D
    return A1, B1, C1, D1


def _weighted_cost(res: np.ndarray, w: np.ndarray) -> float:
    return float(np.sum(w[:, None, None] * (res.real**2 + res.imag**2)))


def _trial(A, B, C, D, G, zs, w, was_stable: bool) -> tuple:
    """``(cost, residual, C R, R B)`` of a candidate; the cost is inf when the candidate makes a
    stable model unstable or its response fails."""
    try:
        eig = np.linalg.eig(A)  # the stability check's and the response's
        if not (was_stable and np.max(np.abs(eig[0])) >= 1.0):
            Gm, CR, RB = _model_response(A, B, C, D, zs, eig)
            res = Gm - G
            return _weighted_cost(res, w), res, CR, RB
    except np.linalg.LinAlgError:
        pass
    return float("inf"), None, None, None


def refine_frequency_fit(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    D: np.ndarray,
    G: np.ndarray,
    zs: np.ndarray,
    weights: np.ndarray | None = None,
    feedthrough: bool = True,
    max_iter: int = 30,
    tol: float = 1e-6,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """Levenberg-Marquardt refinement of a realisation on the frequency-response fit.

    Minimises ``sum_k w_k ||C (z_k I - A)^-1 B + D - G_k||_F^2`` (an output-error criterion in
    the frequency domain) over all entries of ``A, B, C, D``.  The parameterisation is
    redundant (similarity transforms); the damping makes the steps well defined.  Steps that
    move a stable model's pole outside the unit circle or do not lower the cost are
    rejected, so the result is never worse than the start.

    Returns
    -------
    A, B, C, D, info : the refined matrices and ``{"cost0", "cost", "iterations"}``.
    """
    nz = G.shape[0]
    w = np.ones(nz) if weights is None else np.asarray(weights, dtype=float)
    eig0 = np.linalg.eig(A)  # the stability flag's and the first response's
    was_stable = np.max(np.abs(eig0[0])) < 1.0

    Gm, CR, RB = _model_response(A, B, C, D, zs, eig0)
    res = Gm - G
    cost0 = cost = _weighted_cost(res, w)
    # Levenberg-Marquardt with Nielsen's damping update (Madsen, Nielsen & Tingleff 2004, "Methods
    # for non-linear least squares problems", eq. 3.16): the damping follows the gain ratio rho
    # (actual over predicted cost reduction) instead of fixed factors, and starts at the scale of
    # the curvature (mu = 1 relative to diag(J^T J)): the realisation is far from the Gauss-Newton
    # regime at first.  It needs about half the solves of a fixed-factor update (RESULTS-subspace.md).
    mu = 1.0
    nu = 2.0
    it = 0  # steps taken
    for _ in range(max_iter):
        it += 1
        JtJ, g = _normal_equations(CR, RB, res, w, feedthrough)
        dg = np.diag(JtJ).copy()
        dg[dg <= 0] = max(float(dg.max(initial=0.0)), 1.0) * 1e-12
        improved = False
        rel = 0.0
        for _ in range(12):
            try:
                # LU instead of Cholesky: numpy only (importing scipy.linalg costs more than the fit)
                step = np.linalg.solve(JtJ + mu * np.diag(dg), -g)
            except np.linalg.LinAlgError:
                mu *= nu
                nu *= 2.0
                continue
            A1, B1, C1, D1 = _stepped(A, B, C, D, step, feedthrough)
            c1, res1, CR1, RB1 = _trial(A1, B1, C1, D1, G, zs, w, was_stable)
            if np.isfinite(c1) and c1 < cost:
                # predicted reduction of the Gauss-Newton model sum w|r + J s|^2
                predicted = -float(2.0 * (step @ g) + step @ (JtJ @ step))
                rho = (cost - c1) / predicted if predicted > 0 else 0.0
                rel = (cost - c1) / max(cost, 1e-300)
                A, B, C, D, res, CR, RB, cost = A1, B1, C1, D1, res1, CR1, RB1, c1
                mu = max(mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-12)
                nu = 2.0
                improved = True
                break
            mu *= nu
            nu *= 2.0
        if not improved or rel < tol:
            break
    return A, B, C, D, {"cost0": cost0, "cost": cost, "iterations": it}
