"""Step 2 of the stage identification with a PI hysteresis: operator columns and their weight fit.

The classical or modified PI output is linear in its operator weights, ``y = Z w``: the play
operators' outputs ``Z_j`` of every record (from the record's starting state) are the columns
that :class:`~.problem.StageProblem` runs through ``G``.  For fixed ``G`` the weights, creep
weights and one offset per record solve a bounded least-squares problem that keeps the model
invertible, the constraint of the PI identification (:mod:`..identify.weights`): classical,
cumulative weights ``>= eps``; modified, ``w_0 = eps + s + sum q``, ``w_i = p_i - q_i``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..identify.weights import cumulative_map, split_map
from ..models.creep import CreepTerm

__all__ = ["PIColumns", "constraint_map", "N_ALTERNATIONS", "MAX_ROWS"]

#: Rounds of the alternation from each start (the PI fit runs all of them).
N_ALTERNATIONS = 4
#: Least-squares rows per fit (evenly strided); the filters always run over every sample.
MAX_ROWS = 40000


class PIColumns:
    """The operator outputs of a PI hysteresis on every record, and the constrained weight fit.

    Parameters
    ----------
    hysteresis : PIModel or ModifiedPIModel
        Step 1's model: its thresholds fix the columns; its weights are refitted.
    recs : list of (u, y)
        The records, 1-D arrays each.
    kinds : list of str
        Each record's starting state (``"zero"``, ``"ascending"``, ``"descending"``).
    """

    n_alternations = N_ALTERNATIONS
    #: relative drop of the residual below which the alternation stops early (0: never)
    settle = 0.0
    max_rows = MAX_ROWS

    def __init__(self, hysteresis: Any, recs: list, kinds: list[str]) -> None:
        self.model = hysteresis
        self.recs = recs
        self.kinds = kinds
        self.Z = []
        for (u, _), kind in zip(recs, kinds):
            m = hysteresis.with_state(hysteresis.consistent_state(u[0], kind))
            self.Z.append(m.operator_outputs(u)[0])
        r = hysteresis.r
        live = np.flatnonzero(np.max([np.ptp(z, axis=0) for z in self.Z], axis=0) > 1e-3 * max(r[-1], 1e-300))
        self.live = np.union1d(live, [0])
        self.classical = hysteresis.kind == "pi"
        yr = max(float(np.ptp(y)) for _, y in recs)
        ur = max(float(np.ptp(u)) for u, _ in recs)
        self.eps = 0.02 * yr / ur  # PIIdentifier's default min_slope_fraction, slope in operator units

    def search_columns(self, cols: list[np.ndarray], masks: list[np.ndarray], stride: int) -> list[np.ndarray]:
        """Columns the searches for ``G`` run on: all of them (a few tens of operators)."""
        return cols

    def grid_starts(self, problem: Any, cols: list[np.ndarray], masks: list[np.ndarray], order: int) -> list:
        """Further ``(b, a)`` starts of the alternation: none."""
        return []

    def solve_weights(
        self, cols: list[np.ndarray], masks: list[np.ndarray], nc: int, stride: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Constrained LS of ``y`` by ``cols`` plus one offset per record: (weights incl. creep, offsets)."""
        from scipy.optimize import lsq_linear

        J = len(cols)
        p = cols[0].shape[1]
        rows_X, rows_y = [], []
        for j, ((_, y), c, mask) in enumerate(zip(self.recs, cols, masks)):
            idx = np.flatnonzero(mask)[::stride]
            if idx.size == 0:
                continue
            E = np.zeros((idx.size, J))
            E[:, j] = 1.0
            rows_X.append(np.hstack([c[idx], E]))
            rows_y.append(y[idx])
        X = np.vstack(rows_X)
        t = np.concatenate(rows_y)
        # v = (operator variables, creep, offsets); w = T v + shift keeps the model invertible
        T, shift, lb = constraint_map(p - nc, nc, J, self.eps, self.classical)
        scale = np.linalg.norm(X @ T, axis=0)
        scale[scale == 0] = 1.0
        res = lsq_linear((X @ T) / scale, t - X @ shift, bounds=(lb * scale, np.full(lb.size, np.inf)), method="bvls")
        sol = T @ (res.x / scale) + shift
        return sol[:p], sol[p:]

    def hysteresis(self, w, c, offset, taus, dt, in_name, out_name) -> tuple[Any, None]:
        """The PI model of the live weights ``w`` (creep ``c`` of ``taus`` inside it), and no separate creep."""
        weights = np.zeros(self.model.n_operators)
        weights[self.live] = w
        h = replace(self.model, weights=weights, output_offset=float(offset), inputs=(in_name,), outputs=(out_name,))
        if taus:
            h = replace(h, creep=CreepTerm(time_constants=taus, weights=np.maximum(c, 0.0), sample_time=dt))
        return h, None


def constraint_map(m: int, nc: int, J: int, eps: float, classical: bool):
    """``(T, shift, lb)`` with ``x = T v + shift``, ``v >= lb``: the invertibility constraint of
    the PI identification (classical: cumulative weights ``>= eps``; modified: ``w_0 = eps + s +
    sum q``, ``w_i = p_i - q_i``), creep weights ``>= 0``, offsets free."""
    tail = nc + J
    shift = np.zeros(m + tail)
    # the same reformulations as the weight-only fit (weights.py), with the creep and offsets appended
    if classical:
        lb = np.concatenate([np.full(m, eps), np.zeros(nc), np.full(J, -np.inf)])
        return cumulative_map(m, m + tail), shift, lb
    shift[0] = eps
    lb = np.concatenate([np.zeros(2 * m - 1 + nc), np.full(J, -np.inf)])
    return split_map(m, tail), shift, lb
