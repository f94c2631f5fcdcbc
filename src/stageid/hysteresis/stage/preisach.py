"""Step 2 of the stage identification with a Preisach hysteresis: cell weights, creep and dynamics.

The Preisach output is linear in its cell weights (``y = y0 + Phi w``, :mod:`..identify.preisach`),
so the alternation of :class:`~.problem.StageProblem` carries over with the cell states
``Phi_j`` of every record as the columns (:class:`PreisachColumns`, the strategy plugged into
it): for fixed ``G`` the weights solve

    min_{w >= 0, c >= 0, o_j}  sum_j ||o_j + G[Phi_j w + L_j c] - y_j||^2 + lambda ||D w||^2

(``D`` the second differences of the Preisach identification, ``lambda`` = ``smoothing`` times the
mean diagonal of the filtered cells' Gram matrix), by NNLS on the Cholesky factor of the
normal equations with the offsets eliminated (centred columns).  The searches for ``G``
(variable projection, over-parametrised start) run on the leading ``SEARCH_RANK`` singular
directions of the cell states, which carry the hysteresis output to well below the noise; the
weights are always refitted on every cell.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..._errors import IdentificationError
from ..identify.preisach import second_differences
from ..models.creep import CreepTerm
from ..models.preisach import PreisachModel

__all__ = ["PreisachColumns", "preisach_cell_states", "best_start_kinds", "SEARCH_RANK", "MAX_ROWS", "GRID_POLES"]

#: Singular directions of the cell states the dynamics searches run on.
SEARCH_RANK = 24
#: Poles of the lag-and-delay starts of the alternation (:meth:`PreisachColumns.grid_starts`).
GRID_POLES = (0.0, 0.5, 0.9)
#: Least-squares rows per weight fit (evenly strided; the filters run over every sample).
MAX_ROWS = 16000


def preisach_cell_states(u: np.ndarray, model: PreisachModel, kind: str) -> np.ndarray:
    """``Phi``, shape (n_samples, n_cells): up part of every cell from the ``kind`` start at ``u[0]``."""
    from ..kernels.preisach import preisach_regressors

    P, _, top, cur = model.with_state(model.consistent_state(u[0], kind)).memory_arrays(0)
    lo = model.input_range[0]
    x = np.ascontiguousarray(u, dtype=float)
    return preisach_regressors(x, model.n_levels, lo, model.step, P, top, cur)


class PreisachColumns:
    """The Preisach cell states of every record and the non-negative, smoothed weight fit.

    Parameters
    ----------
    hysteresis : PreisachModel
        Step 1's model: its grid fixes the cells; its weights are refitted.
    recs : list of (u, y)
        The records, 1-D arrays each.
    kinds : list of str
        Each record's starting state (``"zero"``, ``"ascending"``, ``"descending"``).
    smoothing : float
        ``lambda`` of the second-difference penalty, relative to the mean diagonal of the
        filtered cells' Gram matrix.
    """

    # the searches see only the leading directions, so the alternation finishes the fit of G:
    # it runs until the residual settles (a few rounds on the FORC records, more on a resonance)
    n_alternations = 30
    settle = 1e-4
    max_rows = MAX_ROWS

    def __init__(self, hysteresis: PreisachModel, recs: list, kinds: list[str], smoothing: float) -> None:
        self.model = hysteresis
        self.recs = recs
        self.kinds = kinds
        self.smoothing = float(smoothing)
        self.Z = [preisach_cell_states(u, hysteresis, kind) for (u, _), kind in zip(recs, kinds)]
        self.live = np.arange(hysteresis.n_operators)
        self.D = second_differences(hysteresis.n_levels)

    def search_columns(self, cols: list[np.ndarray], masks: list[np.ndarray], stride: int) -> list[np.ndarray]:
        """The cell states projected on their ``SEARCH_RANK`` leading right singular vectors (creep lags kept)."""
        m = self.model.n_operators
        stacked = np.vstack([c[np.flatnonzero(mk)[::stride], :m] for c, mk in zip(cols, masks) if mk.any()])
        stacked = stacked - stacked.mean(axis=0)
        _, _, Vt = np.linalg.svd(stacked, full_matrices=False)
        V = Vt[: min(SEARCH_RANK, m)].T
        return [np.hstack([c[:, :m] @ V, c[:, m:]]) for c in cols]

    def grid_starts(self, problem: Any, cols: list[np.ndarray], masks: list[np.ndarray], order: int) -> list:
        """The best of a few lag-and-delay filters (``z^-d (1 - p) / (1 - p z^-1)``, ``d <= order``,
        ``p`` in ``GRID_POLES``) by the weight fit's residual: the searches on the leading
        directions can end in a lead-lag when a plain delay of one sample fits far better (seen
        on the dSPACE FORC records, RESULTS.md section 4d)."""
        nc = cols[0].shape[1] - self.model.n_operators
        best = None
        for d in range(order + 1):
            for p in GRID_POLES:
                b = np.zeros(order + 1)
                b[d] = 1.0 - p
                a = np.zeros(order + 1)
                a[:2] = 1.0, -p
                filtered = problem.filtered((b, a), cols, masks)
                w, off = problem.solve_weights(filtered, masks, nc)
                err = problem.sse(filtered, masks, w, off)
                if best is None or err < best[0]:
                    best = (err, (b, a))
        return [best[1]]

    def solve_weights(
        self, cols: list[np.ndarray], masks: list[np.ndarray], nc: int, stride: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """NNLS of the cell and creep weights with the smoothness penalty; one free offset per record."""
        from scipy.linalg import cho_factor, solve_triangular
        from scipy.optimize import nnls

        p = cols[0].shape[1]
        m = p - nc
        G = np.zeros((p, p))
        rhs = np.zeros(p)
        means = []
        for (_, y), c, mask in zip(self.recs, cols, masks):
            idx = np.flatnonzero(mask)[::stride]
            if idx.size == 0:
                means.append((np.zeros(p), 0.0))
                continue
            X = c[idx]
            mx, my = X.mean(axis=0), float(y[idx].mean())
            Xc = X - mx
            G += Xc.T @ Xc
            rhs += Xc.T @ (y[idx] - my)
            means.append((mx, my))
        lam = self.smoothing * float(np.mean(np.diag(G)[:m]))
        P = G.copy()
        P[:m, :m] += lam * (self.D.T @ self.D)
        # a tiny ridge keeps the factor defined where a column never moves (e.g. a creep lag
        # on a held-out fold); it changes no resolved weight
        P[np.diag_indices(p)] += 1e-12 * max(float(np.max(np.diag(P))), 1e-300)
        try:
            R = cho_factor(P, lower=False)[0]
        except np.linalg.LinAlgError:
            raise IdentificationError("the Preisach stage's weight problem is singular.") from None
        R = np.triu(R)
        w, _ = nnls(R, solve_triangular(R, rhs, trans="T"), maxiter=50 * p)
        if not np.all(np.isfinite(w)):
            raise IdentificationError("the Preisach stage's weight problem gave non-finite weights.")
        offsets = np.array([my - mx @ w for mx, my in means])
        return w, offsets

    def hysteresis(self, w, c, offset, taus, dt, in_name, out_name) -> tuple[PreisachModel, CreepTerm | None]:
        """The Preisach model of the cell weights ``w``, and the creep of ``taus`` with weights ``c`` (or None)."""
        h = PreisachModel(
            self.model.input_range,
            np.maximum(w, 0.0),
            float(offset),
            self.model.state,
            (in_name,),
            (out_name,),
            self.model.input_limits,
        )
        creep = None
        if taus:
            creep = CreepTerm(time_constants=taus, weights=np.maximum(c, 0.0), sample_time=dt)
        return h, creep


def best_start_kinds(model: PreisachModel, recs: list, choice: str) -> list[str]:
    """Per record the starting-state kind with the least residual of ``model`` (own offset), or ``choice``."""
    if choice != "auto":
        return [choice] * len(recs)
    kinds = []
    for u, y in recs:
        best: Any = None
        for kind in ("zero", "ascending", "descending"):
            e = y - model.with_state(model.consistent_state(u[0], kind)).run(u)[0]
            sse = float(np.sum((e - e.mean()) ** 2))
            if best is None or sse < best[0]:
                best = (sse, kind)
        kinds.append(best[1])
    return kinds
