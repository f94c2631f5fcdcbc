"""Held-out scores of every candidate horizon from one Cholesky factor (nested regressions of eq. 9).

:func:`~stageid.subspace.selection.split_statistics` gives each candidate horizon ``p`` the
*central* block of the largest candidate ``P``'s window statistics: the past of horizon ``p``
is window positions ``P-p .. P-1`` and its future ``P .. P+p-1``, so every candidate predicts
from the same point ``P``.  With the regressors ordered by their distance from that point,

    x = [u(P-1); y(P-1); u(P); u(P-2); y(P-2); u(P+1); ...],

the regressors of horizon ``p`` are the leading ``d_p = p (2m + q)`` of horizon ``P``'s, and the
first ``leads`` block rows of ``y_p``, ``y(P) .. y(P+leads-1)``, are the same targets for every
candidate.  Every candidate's normal equations (eq. 16, with a diagonal prior around zero) for
those rows are then leading blocks of the largest one's, and the leading block of a Cholesky
factor is the factor of the leading block: one factorisation and one forward substitution serve
all candidates, each needing only a back substitution of ``leads q`` columns.  numpy has no
triangular solve, so :func:`solve_lower` and :func:`solve_lower_transposed` work block by block
(matrix products, a small dense solve per diagonal block).
"""

from __future__ import annotations

import numpy as np

from ..map.posterior import Prior, prior_identity_diagonal
from ..statistics.hankel_toeplitz import WindowStatistics, regressor_indices

__all__ = [
    "distance_order",
    "lead_rows",
    "solve_lower",
    "solve_lower_transposed",
    "lead_parts",
    "nested_lead_parts",
]

#: Rows per diagonal block of the blocked triangular solves.
TRIANGULAR_BLOCK = 64


def distance_order(horizon: int, n_inputs: int, n_outputs: int) -> tuple[np.ndarray, np.ndarray]:
    """Regressors of eq. 9 ordered by distance from the prediction point (see the module notes).

    Returns ``(window_index, standard_position)``: their positions in the window vector of
    :class:`~stageid.subspace.statistics.hankel_toeplitz.WindowStatistics` and in the standard regressor
    order ``[u_p(k-p); y_p(k-p); u_p(k)]`` of :func:`~stageid.subspace.statistics.hankel_toeplitz.regressor_indices`.
    """
    P, m, q = horizon, n_inputs, n_outputs
    r = m + q
    dist = np.arange(1, P + 1)[:, None]
    u_past = (P - dist) * r + np.arange(m)[None, :]
    y_past = (P - dist) * r + m + np.arange(q)[None, :]
    u_fut = (P + dist - 1) * r + np.arange(m)[None, :]
    window_index = np.concatenate([u_past, y_past, u_fut], axis=1).ravel()
    lookup = np.full(2 * P * r, -1)
    lookup[regressor_indices(P, m, q)[0]] = np.arange(P * (2 * m + q))
    return window_index, lookup[window_index]


def lead_rows(horizon: int, n_inputs: int, n_outputs: int, leads: int) -> np.ndarray:
    """Window positions of the targets ``y(P) .. y(P+leads-1)`` (the first ``leads`` block rows of ``y_p``)."""
    r = n_inputs + n_outputs
    return ((horizon + np.arange(leads))[:, None] * r + n_inputs + np.arange(n_outputs)[None, :]).ravel()


def _block_inverses(L: np.ndarray, block: int) -> list[np.ndarray]:
    """Inverses of the full diagonal blocks ``[k b, (k+1) b)`` of a lower-triangular ``L``: a
    matrix product per block then replaces a dense solve (cheaper; RESULTS-subspace.md)."""
    return [np.linalg.inv(L[a : a + block, a : a + block]) for a in range(0, L.shape[0] - block + 1, block)]


def solve_lower(
    L: np.ndarray, B: np.ndarray, block: int = TRIANGULAR_BLOCK, inverses: list[np.ndarray] | None = None
) -> np.ndarray:
    """``L^-1 B`` for a lower-triangular ``L`` (forward substitution, block by block); ``inverses``
    are the diagonal blocks' inverses (:func:`_block_inverses` of ``L`` or of a larger factor
    whose leading block ``L`` is)."""
    X = np.array(B, dtype=float)
    n = L.shape[0]
    for k, i in enumerate(range(0, n, block)):
        j = min(n, i + block)
        if inverses is not None and k < len(inverses) and j - i == block:
            X[i:j] = inverses[k] @ X[i:j]
        else:
            X[i:j] = np.linalg.solve(L[i:j, i:j], X[i:j])
        if j < n:
            X[j:] -= L[j:, i:j] @ X[i:j]
    return X


def solve_lower_transposed(
    L: np.ndarray, B: np.ndarray, block: int = TRIANGULAR_BLOCK, inverses: list[np.ndarray] | None = None
) -> np.ndarray:
    """``L^-T B`` for a lower-triangular ``L`` (back substitution over the blocks of
    :func:`solve_lower`, last first)."""
    X = np.array(B, dtype=float)
    n = L.shape[0]
    starts = list(range(0, n, block))
    for k in range(len(starts) - 1, -1, -1):
        i = starts[k]
        j = min(n, i + block)
        if inverses is not None and k < len(inverses) and j - i == block:
            X[i:j] = inverses[k].T @ X[i:j]
        else:
            X[i:j] = np.linalg.solve(L[i:j, i:j].T, X[i:j])
        if i > 0:
            X[:i] -= L[i:j, :i].T @ X[i:j]
    return X


def lead_parts(theta: np.ndarray, XX: np.ndarray, YX: np.ndarray, yy: np.ndarray) -> np.ndarray:
    """``sum ||y - theta x||^2`` per target row from ``sum x x^T``, ``sum y x^T`` and ``diag(sum y y^T)``."""
    return yy - 2.0 * np.einsum("rd,rd->r", theta, YX) + np.einsum("rd,rd->r", theta @ XX, theta)


def _ordered(stats: WindowStatistics, xi: np.ndarray, ti: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(XX, YX, diag YY)`` of the regressors ``xi`` and targets ``ti`` (window positions)."""
    rows = stats.W.take(np.concatenate([xi, ti]), axis=0)  # take: cheaper than fancy indexing here
    cols = rows.take(xi, axis=1)
    return cols[: xi.size], cols[xi.size :], rows[xi.size :][np.arange(ti.size), ti]


def nested_lead_parts(
    train: WindowStatistics, val: WindowStatistics, horizons: list[int], leads: int, prior: Prior | None
) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray], np.ndarray, np.ndarray] | None:
    """Training and held-out residuals of the first ``leads`` block rows of eq. 9 for every horizon.

    ``train`` and ``val`` are the statistics of the largest horizon, the last of the ascending
    ``horizons`` (each >= ``leads``); every horizon uses their central block (module notes).
    ``prior`` is the largest horizon's prior: None (flat) or diagonal around zero, whose
    leading part is each smaller horizon's (true of priors scaled by the regressors' energy).

    Returns
    -------
    (held_out, energy, train_top, yy_top) or None
        Per horizon the held-out residual energy and the held-out energy of each target row
        (``leads q`` values, time-major; the same targets for every horizon); the largest
        horizon's training residual and target energy per row.  None when the prior is of
        another kind or the normal equations are not positive definite (the caller then solves
        candidate by candidate).
    """
    P, m, q = train.horizon, train.n_inputs, train.n_outputs
    if prior is not None and (prior.theta0 is not None or np.shape(prior.precision) != (P * (2 * m + q),)):
        return None
    xi, std_pos = distance_order(P, m, q)
    ti = lead_rows(P, m, q, leads)
    XX, YX, yy = _ordered(train, xi, ti)
    diag = np.zeros(xi.size) if prior is None else np.asarray(prior.precision, dtype=float)[std_pos]
    identity = prior_identity_diagonal(None if prior is None else Prior(None, diag), XX)
    XX[np.diag_indices(xi.size)] += diag  # XX is a fresh gather: the information matrix in place
    try:
        L = np.linalg.cholesky(XX)
    except np.linalg.LinAlgError:
        return None
    inverses = _block_inverses(L, TRIANGULAR_BLOCK)  # shared by every candidate's leading block
    M = solve_lower(L, YX.T, inverses=inverses)
    XXv, YXv, yyv = _ordered(val, xi, ti)
    held_out = {}
    for p in horizons:
        d = p * (2 * m + q)
        theta = solve_lower_transposed(L[:d, :d], M[:d], inverses=inverses).T
        held_out[p] = lead_parts(theta, XXv[:d, :d], YXv[:, :d], yyv)
    if not all(np.all(np.isfinite(v)) for v in held_out.values()):
        return None
    # the largest horizon's theta (the loop's last) for its training residual: the MAP identity
    # theta XX theta^T = theta YX^T - theta diag theta^T under priors of material strength
    if identity is not None:
        train_rows = yy - np.einsum("rd,rd->r", theta, YX) - np.einsum("rd,rd,d->r", theta, theta, identity)
    else:
        XX[np.diag_indices(xi.size)] -= diag
        train_rows = lead_parts(theta, XX, YX, yy)
    return held_out, dict.fromkeys(held_out, yyv), train_rows, yy
