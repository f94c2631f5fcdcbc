"""Output-error refinement of a realisation on the frequency response of eq. 9.

The last step of the frequency route of the realisation (see :mod:`.frequency_domain`):
Levenberg-Marquardt over all entries of ``A, B, C, D`` on
``sum_k ||C (z_k I - A)^-1 B + D - G_k||^2``, with the normal equations formed from the
product structure of the Jacobian, never the Jacobian itself.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["refine_frequency_fit", "fit_cost", "model_response", "refinement_bytes", "REFINE_TOL", "MULTI_START_MISFIT"]

#: Relative cost decrease below which the refinement stops: later steps move the response far
#: less than its own uncertainty (measurements: ``benchmarks/RESULTS-subspace.md``).
REFINE_TOL = 3e-3
#: Relative misfit (cost over the response's energy) above which the refinement also runs from
#: the second start: the order cannot fit the system and a closer start need not lead to the
#: better optimum (misfits seen: ``benchmarks/RESULTS-subspace.md``).
MULTI_START_MISFIT = 1e-3


def refinement_bytes(order: int, n_inputs: int, n_outputs: int, n_frequencies: int) -> float:
    """Memory the refinement of an ``order``-state realisation takes: the normal-equation
    matrix over ``A, B, C, D`` (``P^2`` for ``P`` parameters), its damped and solver copies and
    gather temporary, the gather plan (two indices per entry), and the
    ``(n_frequencies, n, n)`` complex resolvent products."""
    n, m, q = float(order), float(n_inputs), float(n_outputs)
    P = n * n + n * m + q * n + q * m
    return 8.0 * 6.0 * P * P + 16.0 * 6.0 * n_frequencies * n * (n + m + q)


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


def model_response(abcd: tuple[np.ndarray, ...], zs: np.ndarray) -> tuple | None:
    """``(numpy.linalg.eig(A), G, C R, R B)`` of ``abcd = (A, B, C, D)`` at the points ``zs``, with
    ``R = (zI - A)^-1`` (None when the eigensolver fails): the cost of a start
    (:func:`fit_cost`) and the first step of :func:`refine_frequency_fit` from it share it."""
    try:
        eig = np.linalg.eig(abcd[0])
        return (eig, *_model_response(*abcd, zs, eig))
    except np.linalg.LinAlgError:
        return None


def fit_cost(abcd: tuple[np.ndarray, ...], G: np.ndarray, zs: np.ndarray, response: tuple | None = None) -> float:
    """``sum |C (zI - A)^-1 B + D - G|^2`` over the frequencies (inf when not finite);
    ``response``: :func:`model_response` of ``abcd`` when the caller has it."""
    response = model_response(abcd, zs) if response is None else response
    if response is None:
        return float("inf")
    c = float(np.sum(np.abs(response[1] - G) ** 2))
    return c if np.isfinite(c) else float("inf")


@lru_cache(maxsize=8)
def _normal_plan(n: int, m: int, q: int, feedthrough: bool) -> tuple[np.ndarray, ...]:
    """Where each entry of the normal equations reads the two products of :func:`_normal_equations`.

    ``Kr = Lr^T Rr`` with the columns of ``Lr``: ``Re Ma`` over the pairs ``i <= k``, ``Re conj(a w)``
    over ``(r, i)`` and ``w``, and of ``Rr``: ``Re Mb`` over ``j <= l``, ``Re conj(b)`` over ``(j, c)``
    and ones; ``Ki = Li^T Ri`` with ``Im Ma`` over ``i < k``, ``Im conj(a w)``, ``Im Mb`` over ``j < l``
    and ``Im conj(b)`` (``Ma``, ``Mb`` Hermitian: their other pairs follow by symmetry).  Every
    entry is ``Kr[.] +- Ki[.]`` (or 0): the plan holds the flat index into ``[Kr, 0]`` and into
    ``[Ki, -Ki, 0]``.  Returns the ``i <= k`` and ``i < k`` pairs (flat) and the two index arrays.
    """
    iu, ku = np.triu_indices(n)
    ia, ka = np.triu_indices(n, 1)
    nsu, nsa = iu.size, ia.size
    sym = np.empty((n, n), dtype=np.intp)
    sym[iu, ku] = sym[ku, iu] = np.arange(nsu)
    asym = np.zeros((n, n), dtype=np.intp)
    asym[ia, ka] = asym[ka, ia] = np.arange(nsa)
    sign = np.zeros((n, n), dtype=np.intp)
    sign[ia, ka], sign[ka, ia] = 1, -1
    ncr, nci = nsu + n * m + 1, nsa + n * m  # columns of Kr and Ki
    nki = (nsa + q * n) * nci
    row_w, col_1 = nsu + q * n, nsu + n * m  # Kr's row of w and column of ones
    nA, nB, nC, nD = n * n, n * m, q * n, (q * m if feedthrough else 0)
    P = nA + nB + nC + nD
    zr, zi = ncr * (row_w + 1), 2 * nki  # the 0 appended to Kr and to [Ki, -Ki]
    ir = np.empty((P, P), dtype=np.intp)
    ii = np.empty((P, P), dtype=np.intp)

    def put(r0, c0, kr, ki=zi, sgn=0):
        # one block (rows = its first two grid axes, columns = the last two) and its mirror
        shape = np.broadcast_shapes(np.shape(kr), np.shape(ki), np.shape(sgn))
        rows, cols = shape[0] * shape[1], shape[2] * shape[3]
        kr = np.broadcast_to(kr, shape).reshape(rows, cols)
        ki = np.where(sgn > 0, ki, np.where(sgn < 0, ki + nki, zi))
        ki = np.broadcast_to(ki, shape).reshape(rows, cols)
        for out, v in ((ir, kr), (ii, ki)):
            out[r0 : r0 + rows, c0 : c0 + cols] = v
            out[c0 : c0 + cols, r0 : r0 + rows] = v.T

    def grid(*sizes):
        return np.meshgrid(*[np.arange(k) for k in sizes], indexing="ij", sparse=True)

    iA, iB, iC, iD = 0, nA, nA + nB, nA + nB + nC
    caw_r, caw_i = nsu + np.arange(q * n).reshape(q, n), nsa + np.arange(q * n).reshape(q, n)  # rows (r, i)
    i, j, k, l = grid(n, n, n, n)  # AA[(i,j),(k,l)] = Re sum Ma[i,k] Mb[j,l]
    put(iA, iA, sym[i, k] * ncr + sym[j, l], asym[i, k] * nci + asym[j, l], -sign[i, k] * sign[j, l])
    i, j, k, c = grid(n, n, n, m)  # AB[(i,j),(k,c)] = Re sum Ma[i,k] conj(b)[j,c]
    put(iA, iB, sym[i, k] * ncr + nsu + j * m + c, asym[i, k] * nci + nsa + j * m + c, -sign[i, k])
    i, j, r, l = grid(n, n, q, n)  # AC[(i,j),(r,l)] = Re sum conj(a w)[r,i] Mb[j,l]
    put(iA, iC, caw_r[r, i] * ncr + sym[j, l], caw_i[r, i] * nci + asym[j, l], -sign[j, l])
    i, c, k, d = grid(n, m, n, m)  # BB[(i,c),(k,c)] = Re sum Ma[i,k]
    put(iB, iB, np.where(c == d, sym[i, k] * ncr + col_1, zr))
    i, c, r, j = grid(n, m, q, n)  # BC[(i,c),(r,j)] = Re sum conj(a w)[r,i] b[j,c]
    put(iB, iC, caw_r[r, i] * ncr + nsu + j * m + c, caw_i[r, i] * nci + nsa + j * m + c, 1)
    r, i, s, j = grid(q, n, q, n)  # CC[(r,i),(r,j)] = Re sum w Mb[i,j]
    put(iC, iC, np.where(r == s, row_w * ncr + sym[i, j], zr))
    if feedthrough:
        i, j, r, c = grid(n, n, q, m)  # AD[(i,j),(r,c)] = Re sum conj(a w)[r,i] conj(b)[j,c]
        put(iA, iD, caw_r[r, i] * ncr + nsu + j * m + c, caw_i[r, i] * nci + nsa + j * m + c, -1)
        i, c, r, d = grid(n, m, q, m)  # BD[(i,c),(r,c)] = Re sum conj(a w)[r,i]
        put(iB, iD, np.where(c == d, caw_r[r, i] * ncr + col_1, zr))
        r, i, s, c = grid(q, n, q, m)  # CD[(r,i),(r,c)] = Re sum w conj(b)[i,c]
        put(iC, iD, np.where(r == s, row_w * ncr + nsu + i * m + c, zr))
        r, c, s, d = grid(q, m, q, m)  # DD = sum w I
        put(iD, iD, np.where((r == s) & (c == d), row_w * ncr + col_1, zr))
    return iu * n + ku, ia * n + ka, ir, ii


def _normal_equations(
    a: np.ndarray, b: np.ndarray, e: np.ndarray, w: np.ndarray, feedthrough: bool
) -> tuple[np.ndarray, np.ndarray]:
    """``J^T J`` and ``J^T r`` of the frequency fit over ``vec(A), vec(B), vec(C), vec(D)``.

    Uses the product structure ``dG/dA_ij = (C R)[:, i] (R B)[j, :]`` so the Jacobian itself
    is never formed: every block is a weighted sum over frequencies of small outer products,
    ``a = C R`` (nz, q, n), ``b = R B`` (nz, n, m), ``e`` the residual (nz, q, m).  All blocks
    of ``J^T J`` are entries of two real products over the frequencies (:func:`_normal_plan`):
    the Hermitian ``Ma = (a w)^H a`` and ``Mb = conj(b) b^T`` need their ``i <= k`` real and
    ``i < k`` imaginary pairs only, about half the flops of the full products.
    """
    nz, q, n = a.shape
    m = b.shape[2]
    su, sa, ir, ii = _normal_plan(n, m, q, feedthrough)
    aw = a * w[:, None, None]
    cb = np.conj(b)
    Ma = np.matmul(np.conj(aw).transpose(0, 2, 1), a).reshape(nz, n * n)  # (z, (i, k))
    Mb = np.matmul(cb, b.transpose(0, 2, 1)).reshape(nz, n * n)  # (z, (j, l))
    nsu, nsa = su.size, sa.size
    Lr, Rr = np.empty((nz, nsu + q * n + 1)), np.empty((nz, nsu + n * m + 1))
    Lr[:, :nsu], Lr[:, nsu:-1], Lr[:, -1] = Ma.real[:, su], aw.real.reshape(nz, q * n), w
    Rr[:, :nsu], Rr[:, nsu:-1], Rr[:, -1] = Mb.real[:, su], b.real.reshape(nz, n * m), 1.0
    Li, Ri = np.empty((nz, nsa + q * n)), np.empty((nz, nsa + n * m))
    Li[:, :nsa], Li[:, nsa:] = Ma.imag[:, sa], -aw.imag.reshape(nz, q * n)
    Ri[:, :nsa], Ri[:, nsa:] = Mb.imag[:, sa], -b.imag.reshape(nz, n * m)
    Ki = (Li.T @ Ri).ravel()
    JtJ = np.append((Lr.T @ Rr).ravel(), 0.0).take(ir)
    JtJ += np.concatenate([Ki, -Ki, [0.0]]).take(ii)
    ew = e * w[:, None, None]
    X = np.matmul(np.conj(a).transpose(0, 2, 1), ew)  # a^H e w per frequency, (z, i, c)
    cbt = cb.transpose(1, 0, 2).reshape(n, nz * m)
    gA = (X.transpose(1, 0, 2).reshape(n, nz * m) @ cbt.T).real.reshape(-1)
    gC = (ew.transpose(1, 0, 2).reshape(q, nz * m) @ cbt.T).real.reshape(-1)
    grads = [gA, X.sum(axis=0).real.reshape(-1), gC]
    if feedthrough:
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
    response: tuple | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """Levenberg-Marquardt refinement of a realisation on the frequency-response fit.

    Minimises ``sum_k w_k ||C (z_k I - A)^-1 B + D - G_k||_F^2`` (an output-error criterion in
    the frequency domain) over all entries of ``A, B, C, D``.  The parameterisation is
    redundant (similarity transforms); the damping makes the steps well defined.  Steps that
    move a stable model's pole outside the unit circle or do not lower the cost are
    rejected, so the result is never worse than the start.  ``response``: the start's
    :func:`model_response` when the caller has it (saves computing it again).

    Returns
    -------
    A, B, C, D, info : the refined matrices and ``{"cost0", "cost", "iterations"}``.
    """
    nz = G.shape[0]
    w = np.ones(nz) if weights is None else np.asarray(weights, dtype=float)
    if response is None:
        eig0 = np.linalg.eig(A)  # the stability flag's and the first response's
        Gm, CR, RB = _model_response(A, B, C, D, zs, eig0)
    else:
        eig0, Gm, CR, RB = response
    was_stable = np.max(np.abs(eig0[0])) < 1.0
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
        damped = np.empty_like(JtJ)
        for _ in range(12):
            try:
                np.copyto(damped, JtJ)
                damped.flat[:: damped.shape[0] + 1] += mu * dg
                # LU instead of Cholesky: numpy only (importing scipy.linalg costs more than the fit)
                step = np.linalg.solve(damped, -g)
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
