"""Step 2 of the identification: the operator weights by constrained linear least squares.

With the thresholds fixed the model is linear in the weights: the operator outputs of every
record (eq. 1, 3 from the record's starting state) are the columns, with one output offset per
record (sensor zeros differ between records) and, optionally, the creep lags of
:mod:`~stageid.hysteresis.models.creep`.  The constraint keeps the model invertible (eq. 5):

* classical PI: every initial-loading slope ``W_j = sum_{i<=j} w_i >= eps`` (bounds on ``W``);
* modified PI: ``w_0 + sum_{i>=1} min(w_i, 0) >= eps``, solved as bounds after writing
  ``w_i = p_i - q_i``, ``w_0 = eps + s + sum q_i`` with ``s, p, q >= 0``;
* creep weights ``c_j >= 0``.

The fit works on the normal equations (``kernels.cp_gram``, or ``kernels.gram`` on the creep columns)
and a non-negative least-squares problem on the Cholesky factor of their reduced form.
"""

from __future__ import annotations

import functools

import numpy as np

from ..._errors import IdentificationError
from ..models.creep import CreepTerm
from ..models.pi import ModifiedPIModel, PIModel

__all__ = ["WeightProblem", "gram_solve", "bounded_gram_lsq", "bounded_gram_lsq_bvls", "cumulative_map", "split_map"]


class WeightProblem:
    """Operator matrices and the constrained least-squares weight fit for fixed thresholds (step 2).

    ``theta`` holds the threshold-search parameters of step 3: the ratio laws ``c0, c1, a0,
    a1, b0, b1``, the centre ``xc`` and the input warp ``q`` (:meth:`thresholds`,
    :meth:`warp`).  :meth:`solve` returns the residual, weights and per-record offsets.
    """

    def __init__(self, recs, r, eps, stride, kind, ridge=0.0, R=1.0, creep=None):
        self.lags = None
        if creep is not None:  # creep lag columns (independent of the thresholds), per record
            term = CreepTerm(time_constants=creep[0], weights=np.zeros(creep[0].size), sample_time=creep[1])
            self.lags = [np.ascontiguousarray(term.lags(u)[np.arange(0, u.size, stride)]) for u, _ in recs]
        self.ridge = ridge
        self.R = R
        # contiguous float64: one compiled variant of the kernels for every caller
        self.recs = [(np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(y, dtype=float)) for u, y in recs]
        self.r = r
        self.eps = eps
        self.stride = stride
        self.kind = kind
        self.y = np.concatenate([y[::stride] for _, y in recs])
        self.rows = [np.arange(0, u.size, stride) for u, _ in recs]

    def thresholds(self, theta: np.ndarray, classical: bool):
        r = self.r
        if classical:
            return r, r, r, r, float(theta[6])
        t = self.operator_positions(r.size)
        # minimum/maximum, not clip: the same values at a fraction of the call cost, once per weight fit
        c = np.minimum(np.maximum(theta[0] + theta[1] * t, 0.0), 1.0)
        a = np.maximum(theta[2] + theta[3] * t, 0.0)
        b = np.minimum(np.maximum(theta[4] + theta[5] * t, 0.0), 1.0)
        ra = a * r
        return r, c * r, ra, b * ra, float(theta[6])

    @staticmethod
    @functools.lru_cache(maxsize=16)
    def operator_positions(n: int) -> np.ndarray:
        """``t_i = i/(n-1) - 1/2``, the operator index the ratio laws of ``theta`` are linear in."""
        t = np.arange(n) / max(n - 1, 1) - 0.5
        t.setflags(write=False)  # cached: shared by every fit
        return t

    def warp(self, theta, classical):
        return 0.0 if classical or len(theta) < 8 else float(theta[7])

    def start_outputs(self, u0, xc, q, thresholds, kind):
        """Operator outputs at the first sample ``u0`` (shape (1,)) for the starting-state ``kind``."""
        r, rc, ra, rb = thresholds
        x = float(u0[0]) - xc
        if q != 0.0:  # the warp of :meth:`warped` on one number, without array calls
            t = abs(x) / self.R
            x += q * self.R * (t * t if t <= 1.0 else 2.0 * t - 1.0)
        up = np.maximum(x - r, np.minimum(x - rc, 0.0))
        down = np.minimum(x + ra, np.maximum(x + rb, 0.0))
        z0 = up if kind == "ascending" else down if kind == "descending" else np.maximum(up, np.minimum(down, 0.0))
        return np.ascontiguousarray(z0)

    def warped(self, x, q):
        """The monotone quadratic input warp of :class:`ModifiedPIModel` (identity for q = 0)."""
        if q == 0.0:
            return x
        t = np.abs(x) / self.R
        return x + q * self.R * np.where(t <= 1.0, t * t, 2.0 * t - 1.0)

    def operator_inputs(self, theta, kinds, classical):
        """Per record: the operator input (centred, warped) and the starting outputs ``z0``."""
        r, rc, ra, rb, xc = self.thresholds(theta, classical)
        q = self.warp(theta, classical)
        for (u, _), kind in zip(self.recs, kinds):
            x = self.warped(u - xc, q)
            # the state before the first sample: z0 is already consistent with x[0]
            yield np.ascontiguousarray(x), self.start_outputs(u[:1], xc, q, (r, rc, ra, rb), kind)

    def matrix(self, theta, kinds, classical):
        from .. import kernels  # numba: imported on first use

        r, rc, ra, rb, _ = self.thresholds(theta, classical)
        blocks = []
        for (x, z0), rows in zip(self.operator_inputs(theta, kinds, classical), self.rows):
            Z, _ = kernels.cp_bank(x, r, rc, ra, rb, z0)
            blocks.append(Z[rows])
        return blocks

    def gram_blocks(self, theta, kinds, classical):
        """Per record ``(Z'Z, Z'y, column sums, rows, sum y)`` of the operator outputs ``Z`` at
        the strided rows, and the largest motion of each operator over the records: accumulated
        as the operators run (:func:`~stageid.hysteresis.kernels.cp_gram`, input warp included),
        no row matrix formed: the cost of every step of the threshold search
        (benchmarks/RESULTS-hysteresis.md, benchmarks/RESULTS-recovery.md)."""
        from .. import kernels  # numba: imported on first use

        r, rc, ra, rb, xc = self.thresholds(theta, classical)
        q = self.warp(theta, classical)
        stats, motion, start = [], np.zeros(r.size), 0
        y = np.ascontiguousarray(self.y, dtype=float)  # the rows' outputs (a bootstrap replaces them)
        for (u, _), kind, kept in zip(self.recs, kinds, self.rows):
            z0 = self.start_outputs(u[:1], xc, q, (r, rc, ra, rb), kind)
            yb = y[start : start + kept.size]
            G, g, s, rows, ysum, low, high = kernels.cp_gram(
                u, yb, xc, q, float(self.R), r, rc, ra, rb, z0, self.stride
            )
            stats.append((G, g, s, rows, ysum))
            np.maximum(motion, high - low, out=motion)
            start += kept.size
        return stats, motion

    def _live(self, blocks=None, motion=None) -> np.ndarray:
        """Columns of the operators that move: one that (almost) never moves gets no weight
        (its weight would be unbounded); the linear term always counts."""
        if motion is None:
            motion = np.max([np.ptp(b, axis=0) for b in blocks], axis=0)
        live = motion > 1e-3 * max(float(self.r[-1]), 1e-300)
        live[0] = True
        return np.flatnonzero(live)

    def _normal_equations(self, columns, m: int, classical: bool):
        """``(G, G_fit, g, y'y)`` of the least-squares fit of ``y`` by the per-record column
        blocks plus one offset per record; ``G`` adds the ridge on the CP weights ``1 .. m-1``
        (not the linear term, creep weights or offsets: a CP operator whose thresholds leave it
        almost still over the data would otherwise get a huge weight that explodes outside the
        identified range), ``G_fit`` is without it."""
        from .. import kernels  # numba: imported on first use

        y = self.y
        stats = []
        start = 0
        for c in columns:
            yb = np.ascontiguousarray(y[start : start + c.shape[0]])
            stats.append((*kernels.gram(np.ascontiguousarray(c), yb), c.shape[0], yb.sum()))
            start += c.shape[0]
        return self._assemble(stats, m, classical)

    def _assemble(self, stats, m: int, classical: bool):
        """The normal equations of :meth:`_normal_equations` from per-record ``(Z'Z, Z'y, column
        sums, rows, sum y)`` of the columns."""
        p = stats[0][0].shape[0]
        J = len(stats)
        G = np.zeros((p + J, p + J))
        g = np.zeros(p + J)
        for j, (Gb, gb, sb, rows, ysum) in enumerate(stats):
            G[:p, :p] += Gb
            G[:p, p + j] = sb
            G[p + j, :p] = sb
            G[p + j, p + j] = rows
            g[:p] += gb
            g[p + j] = ysum
        Gfit = G
        if self.ridge > 0 and not classical:
            G = G.copy()
            lam = self.ridge * float(np.mean(np.diag(G)[:m]))
            G[np.arange(1, m), np.arange(1, m)] += lam
        return G, Gfit, g, float(self.y @ self.y)

    def solve(self, theta, kinds, classical, creep=True):
        """SSE, weights (n,), offsets (n_records,) of the constrained fit (Gram-matrix based);
        with the creep columns when there are any and ``creep`` is true."""
        if self.lags is not None and creep:
            return self.solve_creep(theta, kinds, classical)[:3]

        stats, motion = self.gram_blocks(theta, kinds, classical)
        n = self.r.size
        J = len(stats)
        idx = self._live(motion=motion)
        m = idx.size
        live = stats if m == n else [(G[np.ix_(idx, idx)], g[idx], s[idx], rows, ys) for G, g, s, rows, ys in stats]
        G, Gfit, g, yy = self._assemble(live, m, classical)
        if classical:
            # w = D W with W the cumulative sums (over the live operators), bounds W >= eps
            T = cumulative_map(m, m + J)
            lb = np.concatenate([np.full(m, self.eps), np.full(J, -np.inf)])
            v = bounded_gram_lsq(T.T @ G @ T, T.T @ g, lb)
            sol = T @ v
        else:
            sol = gram_solve(G, g)
            wl = sol[:m]
            if not (wl[0] + np.sum(np.minimum(wl[1:], 0.0)) >= self.eps):
                # w0 = eps + s + sum q, w_i = p_i - q_i (i >= 1), s, p, q >= 0: v = (s, p, q, offsets)
                k = m - 1
                T = split_map(m, J)
                shift = np.zeros(m + J)
                shift[0] = self.eps
                g2 = T.T @ (g - G @ shift)
                lb = np.concatenate([np.zeros(1 + 2 * k), np.full(J, -np.inf)])
                v = bounded_gram_lsq(T.T @ G @ T, g2, lb)
                sol = T @ v + shift
        w = np.zeros(n)
        w[idx] = sol[:m]
        offs = sol[m:]
        sse = yy - 2.0 * float(sol @ g) + float(sol @ Gfit @ sol)
        if self.ridge > 0 and not classical:
            sse += float(sol @ (G - Gfit) @ sol)
        return max(sse, 0.0), w, offs

    def solve_creep(self, theta, kinds, classical):
        """As :meth:`solve` with the creep lag columns (weights ``c >= 0``); also returns c."""
        blocks = self.matrix(theta, kinds, classical)
        n = self.r.size
        J = len(blocks)
        nc = self.lags[0].shape[1]
        idx = self._live(blocks)
        m = idx.size
        p = m + nc  # operator weights, creep weights, then one offset per record
        G, Gfit, g, yy = self._normal_equations(
            [np.hstack([b[:, idx], self.lags[j]]) for j, b in enumerate(blocks)], m, classical
        )
        sol = gram_solve(G, g)
        wl, cl = sol[:m], sol[m:p]
        if classical:
            ok = bool(np.all(np.cumsum(wl) >= self.eps))
        else:
            ok = bool(wl[0] + np.sum(np.minimum(wl[1:], 0.0)) >= self.eps)
        if not (ok and np.all(cl >= 0)):
            shift = np.zeros(p + J)
            if classical:
                # w = D W (cumulative sums, W >= eps), c >= 0, offsets free
                T = cumulative_map(m, p + J)
                lb = np.concatenate([np.full(m, self.eps), np.zeros(nc), np.full(J, -np.inf)])
            else:
                # w0 = eps + s + sum q, w_i = p_i - q_i, c >= 0: v = (s, p, q, c, offsets)
                k = m - 1
                T = split_map(m, nc + J)
                shift[0] = self.eps
                lb = np.concatenate([np.zeros(1 + 2 * k + nc), np.full(J, -np.inf)])
            v = bounded_gram_lsq(T.T @ G @ T, T.T @ (g - G @ shift), lb)
            sol = T @ v + shift
        w = np.zeros(n)
        w[idx] = sol[:m]
        c = np.maximum(sol[m:p], 0.0)
        offs = sol[p:]
        sse = yy - 2.0 * float(sol @ g) + float(sol @ Gfit @ sol)
        if self.ridge > 0 and not classical:
            sse += float(sol @ (G - Gfit) @ sol)
        return max(sse, 0.0), w, offs, c

    def build(self, theta, w, offset, in_name, out_name, lo, hi, identified):
        classical = self.kind == "pi"
        r, rc, ra, rb, xc = self.thresholds(theta, classical)
        # input_limits: the identified input range (the compensator's default drive limits)
        common = dict(
            weights=w,
            input_offset=xc,
            output_offset=float(offset),
            inputs=(in_name,),
            outputs=(out_name,),
            input_limits=identified,
        )
        if classical:
            model = PIModel(r=r, **common)
        else:
            model = ModifiedPIModel(
                r=r, rc=rc, ra=ra, rb=rb, input_warp=self.warp(theta, False), warp_scale=self.R, **common
            )
        u_rest = min(max(0.0, lo), hi)
        return model.with_state(model.consistent_state(u_rest, "zero"))


def gram_solve(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Solution of ``G v = g`` (``G`` a Gram matrix), scaled to unit diagonal first."""
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs = G / np.outer(d, d)
    try:
        v = np.linalg.solve(Gs + 1e-12 * np.eye(G.shape[0]), g / d)
    except np.linalg.LinAlgError:
        v = np.linalg.lstsq(Gs, g / d, rcond=None)[0]
    return v / d


def bounded_gram_lsq(G: np.ndarray, g: np.ndarray, lb: np.ndarray) -> np.ndarray:
    """min v'Gv - 2 g'v subject to v >= lb (``-inf``: free), scaled to unit diagonal first.

    The free unknowns (the offsets) are eliminated by their normal equations (Schur
    complement), the bounded ones shifted to ``c = v - lb >= 0``: an NNLS problem on the
    Cholesky factor of the reduced Gram matrix (Lawson-Hanson, compiled), which does the
    many small fits of the threshold search several times faster than scipy's BVLS.  Where
    the scaled Gram matrix is singular to rounding, :func:`bounded_gram_lsq_bvls`.
    """
    from scipy.optimize import nnls

    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs = G / d[:, None] / d[None, :]
    Gs.flat[:: G.shape[0] + 1] += 1e-10
    gs = g / d
    bounded = np.isfinite(lb)
    free = ~bounded
    order = np.r_[np.flatnonzero(bounded), np.flatnonzero(free)]  # bounded first: blocks by slicing
    nb = int(bounded.sum())
    Gp = Gs[np.ix_(order, order)]
    gp = gs[order]
    try:
        if nb < order.size:
            F = Gp[nb:, nb:]
            B = Gp[:nb, nb:]
            FB = np.linalg.solve(F, B.T)
            Fg = np.linalg.solve(F, gp[nb:])
        else:
            FB, Fg = np.zeros((0, nb)), np.zeros(0)
        S = Gp[:nb, :nb] - Gp[:nb, nb:] @ FB
        c0 = lb[bounded] * d[bounded]
        h = gp[:nb] - Gp[:nb, nb:] @ Fg - S @ c0
        L = np.linalg.cholesky(0.5 * (S + S.T))
        c, _ = nnls(L.T, np.linalg.solve(L, h), maxiter=50 * max(nb, 1))
    except (np.linalg.LinAlgError, RuntimeError):
        return bounded_gram_lsq_bvls(G, g, lb)
    v = np.empty(G.shape[0])
    v[bounded] = c0 + c
    v[free] = Fg - FB @ v[bounded]
    if not np.all(np.isfinite(v)):
        return bounded_gram_lsq_bvls(G, g, lb)
    return v / d


def bounded_gram_lsq_bvls(G: np.ndarray, g: np.ndarray, lb: np.ndarray) -> np.ndarray:
    """min v'Gv - 2 g'v subject to v >= lb, as a bounded least-squares problem on chol(G)."""
    from scipy.optimize import lsq_linear

    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs = G / np.outer(d, d)
    try:
        Rm = np.linalg.cholesky(Gs + 1e-10 * np.eye(G.shape[0])).T
        qy = np.linalg.solve(Rm.T, g / d)
    except np.linalg.LinAlgError:
        # collinear columns (e.g. operators that never move when ``input_range`` is wider than
        # the data, or an operator constant like the offset): Gs is singular to rounding, so use
        # its symmetric square root with the eigenvalues floored instead of the Cholesky factor
        s, V = np.linalg.eigh(0.5 * (Gs + Gs.T))
        s = np.maximum(s, 1e-10 * max(float(s.max()), 1e-300))
        Rm = np.sqrt(s)[:, None] * V.T
        qy = (V.T @ (g / d)) / np.sqrt(s)
    lbs = np.where(np.isfinite(lb), lb * d, -np.inf)
    res = lsq_linear(Rm, qy, bounds=(lbs, np.full_like(lbs, np.inf)), method="bvls", tol=1e-12, max_iter=2000)
    if not np.all(np.isfinite(res.x)):
        raise IdentificationError("the constrained least-squares weight fit failed (non-finite solution).")
    return res.x / d


@functools.lru_cache(maxsize=64)
def cumulative_map(m: int, size: int) -> np.ndarray:
    """``w = T W``: the first ``m`` unknowns as differences of cumulative sums ``W`` (the
    classical model's initial-loading slopes, bounded below by eps); the others unchanged."""
    T = np.eye(size)
    for i in range(m - 1):
        T[i + 1, i] = -1.0
    T.setflags(write=False)  # cached: shared by every fit
    return T


@functools.lru_cache(maxsize=64)
def split_map(m: int, n_free: int) -> np.ndarray:
    """``(w, rest) = T (s, p, q, rest)`` with ``w_0 = s + sum q`` (plus eps, added by the caller)
    and ``w_i = p_i - q_i``: the modified model's bound ``w_0 + sum min(w_i, 0) >= eps`` as
    ``s, p, q >= 0`` (an exact reformulation); the ``n_free`` other unknowns unchanged."""
    k = m - 1
    T = np.zeros((m + n_free, 1 + 2 * k + n_free))
    T[0, 0] = 1.0
    T[0, 1 + k : 1 + 2 * k] = 1.0
    T[1:m, 1 : 1 + k] = np.eye(k)
    T[1:m, 1 + k : 1 + 2 * k] = -np.eye(k)
    T[m:, 1 + 2 * k :] = np.eye(n_free)
    T.setflags(write=False)  # cached: shared by every fit
    return T
