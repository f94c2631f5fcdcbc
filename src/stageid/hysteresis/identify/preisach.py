"""Identification of a discrete Preisach model: non-negative least squares with smoothness.

The output is linear in the cell weights: ``y = y0 + Phi w`` with ``Phi[k, ij]`` the part of
cell ``(i, j)`` that is up at sample ``k`` (the records start demagnetised about their first
input).  The weights solve

    min_{w >= 0, y0}  ||Phi w + y0 - y||^2 + lambda ||D w||^2,

``D`` the second differences along ``alpha`` and along ``beta`` inside the triangle, ``lambda``
= ``smoothing`` (at least ``PRIOR_FLOOR``) times the mean diagonal of ``Phi' Phi``.  The penalty
is a smoothness prior: where the records leave cells undetermined (no reversal pair inside them)
it fills them from their neighbours, while the cells the data determine barely feel it.  Each
record gets its own offset
(centred columns); the stacked records are reduced to the triangular factor ``R`` of their QR
decomposition (``||A w - b|| = ||R w - Q'b||`` up to a constant) and ``scipy.optimize.nnls``
(Lawson-Hanson) solves ``[R; sqrt(lambda) D] w = [Q'b; 0]``, a problem of the cells' size.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..._errors import DataError, IdentificationError
from ...base import Estimator, InstanceOf, Interval, Satisfies
from ...checks import is_real
from ..models.preisach import PreisachModel
from .records import Records, error_percents, read_records, with_former_channels
from .result import PreisachFit, PreisachResult

__all__ = [
    "PreisachIdentifier",
    "PreisachResult",
    "PreisachFit",
    "cell_regressors",
    "second_differences",
    "filled_cells",
]

#: Smallest smoothness weight (relative to the mean diagonal of ``Phi' Phi``): even with
#: ``smoothing=0`` the prior outweighs the data in directions whose singular value is below
#: 1e-6 of the largest (rounding-level information), so those cells take the smoothest values.
PRIOR_FLOOR = 1e-12
#: A cell whose resolution (diagonal of ``(G + lambda D'D)^-1 G``, 1 = set by the data alone)
#: falls below this is counted as filled by the prior.
FILLED_RESOLUTION = 0.5


def _is_range(value: Any) -> bool:
    return (
        isinstance(value, (tuple, list))
        and len(value) == 2
        and all(is_real(v) for v in value)
        and float(value[0]) < float(value[1])
    )


def cell_regressors(u: np.ndarray, input_range: tuple[float, float], n_levels: int) -> np.ndarray:
    """Up parts of the cells ``Phi``, shape (n_samples, n_levels (n_levels + 1) / 2), from the
    state demagnetised about ``u[0]`` (the memory does not depend on the weights)."""
    from ..kernels.preisach import preisach_regressors

    grid = PreisachModel(input_range, np.zeros(n_levels * (n_levels + 1) // 2))
    P, _, top, cur = grid.with_state(grid.consistent_state(u[0])).memory_arrays(0)
    lo, hi = grid.input_range
    return preisach_regressors(np.ascontiguousarray(u, dtype=float), n_levels, lo, grid.step, P, top, cur)


def second_differences(n: int) -> np.ndarray:
    """Rows ``w[a-1] - 2 w[a] + w[a+1]`` along ``alpha`` and along ``beta`` in the triangle."""
    index = {(i, j): i * (i + 1) // 2 + j for i in range(n) for j in range(i + 1)}
    rows = []
    for i, j in index:
        for di, dj in ((1, 0), (0, 1)):
            a, b = (i - di, j - dj), (i + di, j + dj)
            if a in index and b in index:
                r = np.zeros(len(index))
                r[index[a]], r[index[(i, j)]], r[index[b]] = 1.0, -2.0, 1.0
                rows.append(r)
    return np.array(rows).reshape(-1, len(index))


def filled_cells(R: np.ndarray, lam: float, D: np.ndarray) -> int:
    """Cells set by the prior rather than the data: resolution ``diag((G + lam D'D)^-1 G)``
    (``G = R'R``) below ``FILLED_RESOLUTION`` (the model resolution matrix of inverse theory)."""
    G = R.T @ R
    try:
        res = np.diag(np.linalg.solve(G + lam * (D.T @ D), G))
    except np.linalg.LinAlgError:  # a grid too small for second differences, records that miss cells
        res = np.diag(np.linalg.lstsq(G + lam * (D.T @ D), G, rcond=None)[0])
    return int(np.sum(res < FILLED_RESOLUTION))


class PreisachIdentifier(Estimator):
    """Discrete Preisach model from records by NNLS with a smoothness penalty.

    Parameters
    ----------
    n_levels : int
        Cells per axis of the triangular grid (``n (n + 1) / 2`` weights).
    smoothing : float
        ``lambda`` relative to the mean diagonal of the Gram matrix.
    input_range : (float, float), optional
        Range of the grid; default the records' input range.
    inputs, outputs : str, optional
        The input and output channel: of Experiments with several, the column of that name; the
        model's channel names (default: the first Experiment's, else "V" and "y").

    Raises
    ------
    DataError
        From ``fit``: records whose input never moves (they determine no cell; one line).

    Notes
    -----
    Cells that no reversal pair of the records reaches (a grid finer than the records, an input
    that covers part of the triangle) are filled by the smoothness prior, never refused;
    :attr:`PreisachResult.filled_cells` counts them and the summary says so in one line.
    """

    parameter_constraints = {
        "n_levels": [Interval(int, 2, None, closed="left")],
        "smoothing": [Interval(float, 0, None, closed="left")],
        "input_range": [Satisfies(_is_range, "(low, high) with finite low < high"), None],
        "inputs": [InstanceOf(str, "a channel name"), None],
        "outputs": [InstanceOf(str, "a channel name"), None],
    }

    def __init__(
        self,
        n_levels: int = 20,
        smoothing: float = 1e-4,
        input_range: Any = None,
        inputs: str | None = None,
        outputs: str | None = None,
    ) -> None:
        self.n_levels = n_levels
        self.smoothing = smoothing
        self.input_range = input_range
        self.inputs = inputs
        self.outputs = outputs

    @with_former_channels
    def fit(self, data: Any) -> PreisachResult:
        """Identify the weights and the offsets from one or several records (Experiments or
        (u, y) pairs, as :meth:`PIIdentifier.fit <stageid.hysteresis.PIIdentifier.fit>` takes them).

        The former call ``fit(data, inputs, outputs)`` still works, with a DeprecationWarning.
        """
        self.validate_params()
        return self.fit_records(read_records(data, self.inputs, self.outputs))

    def fit_records(self, records: Records) -> PreisachResult:
        """:meth:`fit` on records already read (:func:`~.records.read_records`): not read again."""
        self.validate_params()
        recs = records.recs
        lo = min(float(u.min()) for u, _ in recs)
        hi = max(float(u.max()) for u, _ in recs)
        if self.input_range is None and not lo < hi:
            raise DataError(
                f"a Preisach model needs an input that varies; got a constant input ({lo:g}) in every record."
            )
        if self.input_range is not None:
            lo, hi = (float(v) for v in self.input_range)
        n = int(self.n_levels)
        A, b, means = self._centred_problem(recs, (lo, hi), n)
        lam = max(float(self.smoothing), PRIOR_FLOOR) * float(np.mean(np.sum(A**2, axis=0)))
        D = second_differences(n)
        w = self._solve(A, b, lam, D)
        offsets = tuple(float(my - mp @ w) for mp, my in means)
        names = {"inputs": (records.input_name,), "outputs": (records.output_name,)}
        model = PreisachModel((lo, hi), w, offsets[0], **names, input_limits=(lo, hi))
        residuals = [y - (cell_regressors(u, (lo, hi), n) @ w + y0) for (u, y), y0 in zip(recs, offsets)]
        maxe, rmse = error_percents(recs, residuals)
        return PreisachResult(
            model.with_state(model.consistent_state(recs[0][0][0])),
            tuple(maxe),
            tuple(rmse),
            offsets,
            filled_cells(A, lam, D),
            records.edges(residuals),
            self.clone(),
        )

    def _centred_problem(self, recs: list, input_range: tuple, n: int) -> tuple[np.ndarray, np.ndarray, list]:
        """Centred cell states and outputs of all records stacked (one offset per record)."""
        blocks, rhs, means = [], [], []
        for u, y in recs:
            Phi = cell_regressors(u, input_range, n)
            mp, my = Phi.mean(axis=0), float(y.mean())
            blocks.append(Phi - mp)
            rhs.append(y - my)
            means.append((mp, my))
        # the tall problem compressed to its triangular factor: ||A w - b|| = ||R w - Q'b|| + const,
        # so NNLS and the resolution check work on a square matrix of the cells' size
        Q, R = np.linalg.qr(np.vstack(blocks))
        c = Q.T @ np.concatenate(rhs)
        # the prior fills what the data leave open, but it needs some cell that the input moves
        if not np.any(np.abs(R) > 0):
            u0 = recs[0][0][0]
            raise DataError(
                f"a Preisach model needs an input that moves across its grid [{input_range[0]:g}, "
                f"{input_range[1]:g}]; got a constant input ({u0:g}) in every record."
            )
        return R, c, means

    def _solve(self, R: np.ndarray, c: np.ndarray, lam: float, D: np.ndarray) -> np.ndarray:
        from scipy.optimize import nnls

        w, _ = nnls(np.vstack([R, np.sqrt(lam) * D]), np.r_[c, np.zeros(D.shape[0])], maxiter=50 * R.shape[1])
        if not np.all(np.isfinite(w)):
            raise IdentificationError("the Preisach weight problem gave non-finite weights.")
        return w
