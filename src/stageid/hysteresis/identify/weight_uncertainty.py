"""Uncertainty of the PI / modified-PI weights: block-robust least-squares covariance.

With the thresholds fixed (step 1, and step 3's search for the modified PI) the output is
linear in the weights, the offsets and the creep weights, ``y = X beta + e``, solved under the
invertibility bounds of :mod:`.weights`.  The residuals of a hysteresis fit are rarely white
(coloured sensor noise, model error that repeats on every branch), so ``sigma^2 (X^T X)^-1`` is
optimistic.  Two estimates that allow for it:

* ``"sandwich"``: ``(X^T X)^-1 (sum_b X_b^T e_b e_b^T X_b) (X^T X)^-1 * N/(N-p) * B/(B-1)``, the
  residual cut into ``B`` blocks of ``BLOCK_FACTOR`` correlation lengths (at least
  ``MIN_BLOCKS`` blocks), ``p`` unknowns: the cluster-robust covariance with its usual
  small-sample corrections.  Exact to first order while no bound is active; one pass, so it
  costs less than the fit.
* ``"bootstrap"``: the wild block bootstrap that reproduces it, refitted under the bounds: each
  draw keeps the fitted output and flips the sign of the residual block by block (Rademacher),
  ``y* = X beta_hat + s_b(t) e(t) sqrt(N/(N-p)) sqrt(B/(B-1))``, and the problem's own bounded
  solver refits it.  A weight pinned at a bound scatters less, which the sandwich cannot see;
  200 refits cost ~100 classical fits.
* ``"auto"`` takes the sandwich unless a bound is active at the estimate.

Whole input cycles were the first choice of block; an identification record has only ~10 of
them, and a cluster-robust variance from 10 clusters for ~10 unknowns came out ~1.7x too small
in std (studies/uncertainty_closedloop/RESULTS.md, section 3).  Not covered: the uncertainty of
the thresholds the modified PI searched (held at their optimum) and of the starting states;
the modified PI's small ridge on the CP weights is left out of the sandwich.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.fft as sfft

from ..._errors import ModelError

__all__ = [
    "UNCERTAINTY_METHODS",
    "WeightUncertainty",
    "weight_uncertainty",
    "block_labels",
    "correlation_length",
    "plot_loop_band",
]

#: a block spans this many correlation lengths of the residual (its memory, with margin)
BLOCK_FACTOR = 10
#: at least this many blocks: a cluster-robust variance from few clusters is biased low
MIN_BLOCKS = 40


@dataclass(frozen=True, eq=False)
class WeightUncertainty:
    """Covariance of an identified PI model's linear parameters.

    Attributes
    ----------
    parameter_covariance : ndarray of shape (k, k)
        Over ``[weights (n_operators), output_offset, creep weights (n_lags)]``, the offset
        being the first record's (the model's ``output_offset``).
    n_operators : int
    method : str
        "sandwich" or "bootstrap" (module notes).
    n_blocks : int
        Residual blocks the estimate used.
    """

    parameter_covariance: np.ndarray
    n_operators: int
    method: str
    n_blocks: int

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of the weights, shape (n_operators, n_operators)."""
        n = self.n_operators
        return self.parameter_covariance[:n, :n]

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each weight, shape (n_operators,)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def output_band(self, model: Any, u: object, dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(y, std)`` of ``model`` simulated on ``u`` from its state, shape (n_samples,) each.

        The output is linear in the weights, the offset and the creep weights, so its variance
        is ``diag(Z Sigma Z^T)`` with ``Z`` the operator outputs, ones and creep lags on ``u``.

        Raises
        ------
        ModelError
            When ``model`` has another number of operators than the covariance.
        """
        if model.n_operators != self.n_operators:
            raise ModelError(
                f"the weight covariance is for {self.n_operators} operators; got a model with {model.n_operators}."
            )
        y = np.asarray(model.simulate(u, dt), dtype=float).reshape(-1)
        Z, _ = model.operator_outputs(u)
        cols = [Z, np.ones((Z.shape[0], 1))]
        creep = getattr(model, "creep", None)
        k_creep = self.parameter_covariance.shape[0] - self.n_operators - 1
        if creep is not None and k_creep:
            uu = np.asarray(u, dtype=float).reshape(-1)
            unit = [replace(creep, weights=np.eye(k_creep)[k]).run(uu, dt)[0] for k in range(k_creep)]
            cols.append(np.column_stack(unit))
        X = np.hstack(cols)
        S = self.parameter_covariance[: X.shape[1], : X.shape[1]]
        return y, np.sqrt(np.clip(((X @ S) * X).sum(axis=1), 0.0, None))


def correlation_length(e: np.ndarray, threshold: float = float(np.exp(-1.0))) -> int:
    """First lag (>= 1) at which the autocorrelation of ``e`` falls below ``threshold``."""
    e = np.asarray(e, dtype=float) - np.mean(e)
    n = e.size
    n_fft = sfft.next_fast_len(2 * n)
    acf = sfft.irfft(np.abs(sfft.rfft(e, n_fft)) ** 2, n_fft)[:n]
    if acf[0] <= 0:
        return 1
    below = np.flatnonzero(acf / acf[0] < threshold)
    return int(below[0]) if below.size else n


def block_labels(e: np.ndarray, n_rows: list[int]) -> np.ndarray:
    """Block index of every least-squares row: blocks of ``BLOCK_FACTOR`` residual correlation
    lengths, never crossing a record's end, at least ``MIN_BLOCKS`` blocks in all."""
    length = BLOCK_FACTOR * correlation_length(e)
    length = max(1, min(length, sum(n_rows) // MIN_BLOCKS))
    labels, base = [], 0
    for n in n_rows:
        lab = np.arange(n) // length
        labels.append(base + lab)
        base += int(lab[-1]) + 1 if n else 0
    return np.concatenate(labels)


UNCERTAINTY_METHODS = ("auto", "sandwich", "bootstrap")


def weight_uncertainty(
    problem: Any,
    theta: np.ndarray,
    kinds: list[str],
    classical: bool,
    method: str = "auto",
    solution: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None,
    n_draws: int = 200,
    seed: int = 0,
) -> WeightUncertainty:
    """Covariance of the linear parameters of a :class:`~stageid.hysteresis.identify.weights.WeightProblem` (module notes).

    ``theta`` and ``kinds`` are the fit's final thresholds and starting states; ``solution`` =
    ``(weights, offsets, creep weights or None)`` of the fit when known (else solved again).
    """
    blocks = problem.matrix(theta, kinds, classical)
    has_creep = problem.lags is not None
    if solution is not None:
        w, offs, c = solution
        c = np.zeros(0) if c is None else np.asarray(c, dtype=float)
    elif has_creep:
        _, w, offs, c = problem.solve_creep(theta, kinds, classical)
    else:
        _, w, offs = problem.solve(theta, kinds, classical)
        c = np.zeros(0)
    X = _design(problem, blocks)
    beta = np.concatenate([w, offs, c])
    fitted = X @ beta
    resid = problem.y - fitted
    labels = block_labels(resid, [rows.size for rows in problem.rows])
    n_blocks = int(labels.max()) + 1
    # the solver gives operators that never move no weight (exactly 0): they carry no variance
    live = np.flatnonzero(np.concatenate([(w != 0) | (np.arange(w.size) == 0), np.ones(offs.size + c.size, bool)]))
    n_rows = resid.size
    scale2 = n_rows / max(n_rows - live.size, 1) * n_blocks / max(n_blocks - 1, 1)
    if method == "auto":
        method = "bootstrap" if _bound_active(w, problem.eps, classical) else "sandwich"
    if method == "sandwich":
        cov = _sandwich(X[:, live], resid, labels, n_blocks) * scale2
        full = np.zeros((beta.size, beta.size))
        full[np.ix_(live, live)] = cov
    else:
        draws = _bootstrap(
            problem, blocks, theta, kinds, classical, fitted, resid, labels, np.sqrt(scale2), n_draws, seed
        )
        full = np.atleast_2d(np.cov(draws, rowvar=False))
    # keep [weights, first offset, creep]
    n, J = w.size, offs.size
    keep = np.concatenate([np.arange(n + 1), n + J + np.arange(c.size)])
    return WeightUncertainty(full[np.ix_(keep, keep)], n, method, n_blocks)


def _design(problem: Any, blocks: list[np.ndarray]) -> np.ndarray:
    """``X`` of ``y = X [w; offsets; c]`` over the least-squares rows of every record."""
    J = len(blocks)
    rows = []
    for j, Z in enumerate(blocks):
        onehot = np.zeros((Z.shape[0], J))
        onehot[:, j] = 1.0
        parts = [Z, onehot] + ([problem.lags[j]] if problem.lags is not None else [])
        rows.append(np.hstack(parts))
    return np.vstack(rows)


def _bound_active(w: np.ndarray, eps: float, classical: bool) -> bool:
    """Whether the invertibility bound of :mod:`.weights` holds with equality at ``w``."""
    tol = 1e-6 * max(abs(eps), float(np.max(np.abs(w))), 1e-300)
    if classical:
        W = np.cumsum(w)
        return bool(np.any(W[w != 0] <= eps + tol))
    return bool(w[0] + np.sum(np.minimum(w[1:], 0.0)) <= eps + tol)


def _sandwich(X: np.ndarray, e: np.ndarray, labels: np.ndarray, n_blocks: int) -> np.ndarray:
    """``(X^T X)^-1 (sum_b X_b^T e_b e_b^T X_b) (X^T X)^-1`` (pseudo-inverse after unit-diagonal scaling)."""
    starts = np.flatnonzero(np.diff(labels, prepend=-1))  # labels are contiguous and increasing
    U = np.add.reduceat(X * e[:, None], starts, axis=0)
    H = X.T @ X
    d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
    Hi = np.linalg.pinv(H / np.outer(d, d), rcond=1e-12, hermitian=True) / np.outer(d, d)
    return Hi @ (U.T @ U) @ Hi


def _bootstrap(problem, blocks, theta, kinds, classical, fitted, resid, labels, scale, n_draws, seed) -> np.ndarray:
    """Draws ``[w; offsets; c]`` of the wild block bootstrap, each refitted under the bounds."""
    # the operator outputs depend on the input alone: computed once, the draws only change y
    fixed = copy.copy(problem)
    fixed.matrix = lambda *_: blocks
    rng = np.random.default_rng(seed)
    n_blocks = int(labels.max()) + 1
    out = []
    for _ in range(int(n_draws)):
        fixed.y = fitted + scale * rng.choice((-1.0, 1.0), size=n_blocks)[labels] * resid
        if problem.lags is not None:
            _, wd, od, cd = fixed.solve_creep(theta, kinds, classical)
        else:
            (_, wd, od), cd = fixed.solve(theta, kinds, classical), np.zeros(0)
        out.append(np.concatenate([wd, od, cd]))
    return np.array(out)


def plot_loop_band(
    model: Any,
    uncertainty: WeightUncertainty,
    u: object,
    y: object | None = None,
    dt: float | None = None,
    xlabel: str = "input [V]",
    ylabel: str = "output",
    title: str = "",
) -> Any:
    """The simulated loop with its +-1.96 std band (95 % for a Gaussian error), and the band over time.

    Left: the model's loop on ``u`` with the band's edges (and the measured ``y`` when given);
    right: the band's half-width along the record beside the model's error when ``y`` is given.
    Returns a matplotlib figure (Agg-safe).
    """
    from ...plots.style import subplots

    uu = np.asarray(u, dtype=float).reshape(-1)
    yh, s = uncertainty.output_band(model, uu, dt)
    fig, axes = subplots(1, 2, figsize=(10.0, 4.0), squeeze=False)
    ax, ax2 = axes[0]
    if y is not None:
        ax.plot(uu, np.asarray(y, dtype=float).reshape(-1), lw=0.6, color="0.6", label="measured")
    ax.plot(uu, yh, lw=0.8, color="C0", label="model")
    ax.plot(uu, yh + 1.96 * s, lw=0.5, color="C1", ls="--", label="+-1.96 std (weights)")
    ax.plot(uu, yh - 1.96 * s, lw=0.5, color="C1", ls="--")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend()
    n = np.arange(uu.size)
    ax2.fill_between(n, -1.96 * s, 1.96 * s, color="C1", alpha=0.3, label="+-1.96 std")
    if y is not None:
        ax2.plot(n, np.asarray(y, dtype=float).reshape(-1) - yh, lw=0.6, color="C0", label="measured - model")
    ax2.set_xlabel("sample")
    ax2.set_ylabel(ylabel)
    ax2.legend()
    if title:
        fig.suptitle(title)
    return fig
