"""Uncertainty of the PI / modified-PI weights: a wild block bootstrap of the residuals (issue 20).

With the thresholds fixed (step 1, and step 3's search for the modified PI) the output is
linear in the weights, the offsets and the creep weights, ``y = X w + e``, solved under the
invertibility bounds of :mod:`.weights`.  The residuals of a hysteresis fit are rarely white
(coloured sensor noise, model error that repeats on every branch), so ``sigma^2 (X^T X)^-1`` is
optimistic, and it ignores the bounds.  Instead each draw keeps the fitted output, flips the
sign of the residual block by block at random (Rademacher), and refits with the problem's own
bounded solver:

    y* = X w_hat + s_b(t) e(t) sqrt(N / (N - p)) sqrt(B / (B - 1)),   s_b = +-1 per block b,

``p`` the unknowns, ``B`` the blocks: the small-sample corrections of a cluster-robust
covariance, which this bootstrap reproduces for an unconstrained problem.  Blocks span
``BLOCK_FACTOR`` correlation lengths of the residual, so its memory stays inside a block, with
at least ``MIN_BLOCKS`` blocks.  Whole input cycles were the first choice of block; an
identification record has only ~10 of them, and a cluster-robust variance from 10 clusters for
~10 unknowns came out ~1.7x too small in std (studies/uncertainty_closedloop/RESULTS.md).  The
bounds act on every draw (a weight pinned at its bound scatters less), and the draws give the
band of any simulated output directly (:meth:`WeightUncertainty.output_band`).

Not covered: the uncertainty of the thresholds the modified PI searched (held at their
optimum) and of the starting states.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.fft as sfft

from .._errors import ModelError

__all__ = ["WeightUncertainty", "bootstrap_weights", "block_labels", "correlation_length", "plot_loop_band"]

#: a block spans this many correlation lengths of the residual (its memory, with margin)
BLOCK_FACTOR = 10
#: at least this many blocks: a cluster-robust variance from few clusters is biased low
MIN_BLOCKS = 40


@dataclass(frozen=True, eq=False)
class WeightUncertainty:
    """Bootstrap draws of an identified PI model's linear parameters.

    Attributes
    ----------
    weights : ndarray of shape (n_draws, n_operators)
    output_offsets : ndarray of shape (n_draws,)
        The first record's offset in each draw (the model's ``output_offset``).
    creep_weights : ndarray of shape (n_draws, n_lags) or None
    n_clusters : int
        Blocks resampled.
    """

    weights: np.ndarray
    output_offsets: np.ndarray
    creep_weights: np.ndarray | None
    n_clusters: int

    @property
    def n_draws(self) -> int:
        return int(self.weights.shape[0])

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each weight, shape (n_operators,)."""
        return self.weights.std(axis=0, ddof=1)

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of the weights, shape (n_operators, n_operators)."""
        return np.atleast_2d(np.cov(self.weights, rowvar=False))

    def draw_models(self, model: Any) -> list[Any]:
        """``model`` with each draw's weights, offset and creep weights (thresholds and state kept)."""
        out = []
        for k in range(self.n_draws):
            m = replace(model, weights=self.weights[k], output_offset=float(self.output_offsets[k]))
            if self.creep_weights is not None and getattr(model, "creep", None) is not None:
                m = replace(m, creep=replace(model.creep, weights=np.maximum(self.creep_weights[k], 0.0)))
            out.append(m.with_state(model.state))
        return out

    def output_band(self, model: Any, u: object, dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(y, std)`` of ``model`` simulated on ``u``: its output and the draws' std, shape (n_samples,).

        Raises
        ------
        ModelError
            When ``model`` has another number of operators than the draws.
        """
        if model.n_operators != self.weights.shape[1]:
            raise ModelError(
                f"the weight draws are for {self.weights.shape[1]} operators; got a model with {model.n_operators}."
            )
        y = np.asarray(model.simulate(u, dt), dtype=float).reshape(-1)
        sims = np.array([np.asarray(m.simulate(u, dt), dtype=float).reshape(-1) for m in self.draw_models(model)])
        return y, sims.std(axis=0, ddof=1)


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


def bootstrap_weights(
    problem: Any,
    theta: np.ndarray,
    kinds: list[str],
    classical: bool,
    n_draws: int = 200,
    seed: int = 0,
) -> WeightUncertainty:
    """Wild cluster bootstrap of the weights of a :class:`~stageid.hysteresis.weights.WeightProblem` (module notes).

    ``theta`` and ``kinds`` are the final thresholds and starting states of the fit; the
    problem's own bounded solver refits every draw.
    """
    blocks = problem.matrix(theta, kinds, classical)
    has_creep = problem.lags is not None
    if has_creep:
        _, w, offs, c = problem.solve_creep(theta, kinds, classical)
    else:
        _, w, offs = problem.solve(theta, kinds, classical)
    fitted = []
    for j, Z in enumerate(blocks):
        f = Z @ w + offs[j]
        fitted.append(f + problem.lags[j] @ c if has_creep else f)
    fitted = np.concatenate(fitted)
    resid = problem.y - fitted
    labels = block_labels(resid, [rows.size for rows in problem.rows])
    n_clusters = int(labels.max()) + 1
    n_rows, n_unknowns = resid.size, w.size + offs.size + (c.size if has_creep else 0)
    scale = np.sqrt(n_rows / max(n_rows - n_unknowns, 1)) * np.sqrt(n_clusters / max(n_clusters - 1, 1))
    # the operator outputs depend on the input alone: computed once, the draws only change y
    fixed = copy.copy(problem)
    fixed.matrix = lambda *_: blocks
    rng = np.random.default_rng(seed)
    W, O, C = [], [], []
    for _ in range(int(n_draws)):
        signs = rng.choice((-1.0, 1.0), size=n_clusters)
        fixed.y = fitted + scale * signs[labels] * resid
        if has_creep:
            _, wd, od, cd = fixed.solve_creep(theta, kinds, classical)
            C.append(cd)
        else:
            _, wd, od = fixed.solve(theta, kinds, classical)
        W.append(wd)
        O.append(od[0])
    return WeightUncertainty(np.array(W), np.array(O), np.array(C) if has_creep else None, n_clusters)


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
    from ..plots._style import subplots

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
