"""Output (noise) weighting of the realisation and the selection.

The regression of eq. 9-18 does not depend on how the outputs are weighted, but the
realisation and the selection do: the in-band response of eq. 9 solves ``p q`` equations for
``q`` outputs, the SVD of Lemma 1 / its frequency counterpart and the output-error refinement
trade the outputs against each other, and a held-out score averaged over the outputs is
dominated by the noisiest.  Weighting every output alike (unit RMS) gives a small coupling
output that is mostly sensor noise as much weight as the driven output.  The fit therefore
weighs noise-whitened outputs, as CVA / maximum-likelihood weighting does: each output is
multiplied by the inverse of its noise standard deviation, estimated from the eq. 9 residual
(``noise_cov`` averaged over the ``p`` block rows of ``y_p``).  This stays unit-invariant (a
change of units scales an output's signal and noise alike) and equals unit-RMS weighting when
every output has the same relative noise.  The noise std is floored at ``NOISE_STD_FLOOR``
times the output's RMS, so noise-free data weigh the outputs as unit RMS does.  What the
weighting changed on the P-558 study is in ``studies/hankel_map/RESULTS.md``.
"""

from __future__ import annotations

import numpy as np

from ..map.posterior import Posterior
from ..statistics.hankel_toeplitz import WindowStatistics, row_residuals
from ..statistics.theta_response import ThetaSpread

__all__ = [
    "NOISE_STD_FLOOR",
    "output_weights",
    "noise_weights",
    "training_weights",
    "weight_scales",
    "weighted_theta",
    "weighted_parts",
]

#: Floor of an output's noise std, as a fraction of its RMS: noise-free records then weigh the
#: outputs as unit RMS does.
NOISE_STD_FLOOR = 1e-3


def output_weights(post: Posterior) -> np.ndarray:
    """Weights of the outputs in the realisation and the order selection: the inverse of each output's noise std.

    The noise variance of output ``i`` is the mean over the ``p`` block rows of ``y_p`` of the
    diagonal of ``post.noise_cov`` (the eq. 9 residual); the std is floored at
    ``NOISE_STD_FLOOR`` times the output's RMS over the posterior's windows (noise-free
    outputs).  The weights are scaled so that the largest is 1.
    """
    p, q = post.horizon, post.n_outputs
    noise_var = np.diag(post.noise_cov).reshape(p, q).mean(axis=0)
    if len(post.data_sums) == 3 and post.n_windows > 0:
        mean_square = np.diag(post.data_sums[2]).reshape(p, q).mean(axis=0) / post.n_windows
    else:  # no data sums: the channels' own scale (unit RMS in the fit's coordinates)
        mean_square = np.ones(q)
    return noise_weights(noise_var, mean_square)


def noise_weights(noise_var: np.ndarray, mean_square: np.ndarray) -> np.ndarray:
    """``1 / max(noise std, NOISE_STD_FLOOR * RMS)`` per output, the largest scaled to 1."""
    q = noise_var.size
    noise = np.sqrt(np.clip(noise_var, 0.0, None))
    std = np.maximum(noise, NOISE_STD_FLOOR * np.sqrt(np.clip(mean_square, 0.0, None)))
    ok = np.isfinite(std) & (std > 0)
    if not ok.any():
        return np.ones(q)
    # an output that is zero (and noise-free) in these records: its weight does not matter
    std = np.where(ok, std, np.max(std[ok]))
    w = 1.0 / std
    return w / np.max(w)


def training_weights(theta: np.ndarray, stats: WindowStatistics) -> np.ndarray:
    """:func:`noise_weights` from the training residual of ``theta`` on ``stats``."""
    XX, _, YY = stats.blocks()
    p, q = stats.horizon, stats.n_outputs
    dof = max(stats.n_windows - XX.shape[0], 1.0)
    mean_square = np.diag(YY).reshape(p, q).mean(axis=0) / max(stats.n_windows, 1.0)
    return noise_weights(row_residuals(theta, stats).reshape(p, q).mean(axis=0) / dof, mean_square)


def weight_scales(w: np.ndarray, p: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Scales of the rows of ``y_p`` (``w`` per block) and of the regressor ``x`` (past outputs over ``w``)."""
    wp = np.tile(w, p)
    return wp, np.concatenate([np.ones(p * m), 1.0 / wp, np.ones(p * m)])


def weighted_theta(theta: np.ndarray, w: np.ndarray, p: int, m: int, q: int) -> np.ndarray:
    """``theta`` of eq. 9 for the outputs ``w * y``: rows times ``w``, past-output columns over ``w``."""
    rows, cols = weight_scales(w, p, m)
    return theta * rows[:, None] * cols[None, :]


def weighted_parts(post: Posterior) -> tuple[ThetaSpread, np.ndarray]:
    """``theta`` and its covariance factors for the noise-whitened outputs the realisation fits
    (``p P`` for the window overlap: windows counted as independent), and the output weights."""
    p, m, q = post.horizon, post.n_inputs, post.n_outputs
    w = output_weights(post)
    wp, c = weight_scales(w, p, m)
    theta_w = weighted_theta(post.theta, w, p, m, q)
    return ThetaSpread(theta_w, post.covariance * p * np.outer(c, c), post.noise_cov * np.outer(wp, wp), p, m, q), w
