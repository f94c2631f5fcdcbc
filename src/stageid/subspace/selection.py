"""Selection of the horizon ``p`` and of the model order by held-out prediction error.

Cao & Chen (2013) choose ``p`` (Fig. 4) and the order (Tables 4-6) by the prediction error
on data not used for the fit.  Here:

* every record is cut into 8 equal segments and 2 of them (the 3rd and 7th for the default
  ``validation_fraction`` 0.25) are held out: interleaving keeps the held-out part
  representative of chirps, whose frequency changes with time;
* the horizon is chosen by the normalised multi-step prediction error of eq. 9 on the
  held-out windows, which follows from the held-out :class:`WindowStatistics` alone
  (no pass over the data per candidate);
* the order is chosen by the simulation error on the held-out segments of each candidate
  model realised from the training segments (the smallest order within 0.1 % of the best);
* both scores weigh the outputs by the ``weights`` ``HankelMAP`` passes (the inverse noise
  std of each output), so that small noise-dominated coupling outputs do not decide.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .hankel_toeplitz import WindowStatistics

__all__ = ["SelectionTable", "prediction_error", "default_horizons", "simulation_error"]


@dataclass(frozen=True)
class SelectionTable:
    """Error versus a hyper-parameter (``kind`` = "horizon" or "order").

    ``values[i]`` was scored ``errors[i]`` (normalised: error energy / output energy, mean
    over outputs, or with output weights the ratio of the weighted sums; ``inf`` for unusable
    candidates); ``chosen`` is the selected value.
    """

    kind: str
    values: tuple[int, ...]
    errors: tuple[float, ...]
    chosen: int

    def to_text(self) -> str:
        """A two-column text table."""
        lines = [f"{self.kind:>8}  held-out error"]
        for v, e in zip(self.values, self.errors):
            mark = "  <- chosen" if v == self.chosen else ""
            lines.append(f"{v:>8d}  {e:.6g}{mark}")
        return "\n".join(lines)


def default_horizons(n_inputs: int, n_outputs: int, n_windows: int, max_regressors: int = 700) -> list[int]:
    """Candidate horizons: 8 .. 80, keeping ``d = p (2m + q) <= max_regressors`` and ``d <= n_windows / 10``."""
    per = 2 * n_inputs + n_outputs
    cands = [8, 12, 16, 20, 25, 30, 40, 50, 60, 80]
    ok = [p for p in cands if p * per <= max_regressors and p * per * 10 <= n_windows]
    if not ok:
        ok = [max(1, min(8, max_regressors // per, n_windows // (10 * per)))]
    return ok


def prediction_error(theta: np.ndarray, stats: WindowStatistics, weights: np.ndarray | None = None) -> float:
    """Normalised held-out multi-step prediction error of eq. 9.

    ``sum ||y_p - theta x||^2 / sum ||y_p||^2`` per output channel (over all ``p`` block rows),
    averaged over the output channels; with ``weights`` (one per output, e.g. the inverse noise
    std) the ratio of the weighted sums ``sum_i w_i^2 err_i / sum_i w_i^2 energy_i`` instead
    (the same when ``w_i^2`` is proportional to ``1 / energy_i``).
    """
    YY = stats.blocks()[2]
    q = stats.n_outputs
    res_c = row_residuals(theta, stats).reshape(stats.horizon, q).sum(axis=0)
    energy = np.diag(YY).reshape(stats.horizon, q).sum(axis=0)
    energy = np.where(energy > 0, energy, 1.0)
    return _normalised(np.clip(res_c, 0.0, None), energy, weights)


def row_residuals(theta: np.ndarray, stats: WindowStatistics) -> np.ndarray:
    """``sum ||y_p - theta x||^2`` over the windows of ``stats``, per row of ``y_p`` (``p q`` values)."""
    XX, YX, YY = stats.blocks()
    return np.diag(YY) - 2.0 * np.einsum("rd,rd->r", theta, YX) + np.einsum("rd,rd->r", theta @ XX, theta)


def _normalised(err: np.ndarray, energy: np.ndarray, weights: np.ndarray | None) -> float:
    """``mean(err / energy)``, or ``sum(w^2 err) / sum(w^2 energy)`` with weights."""
    if weights is None:
        return float(np.mean(err / energy))
    w2 = np.asarray(weights, dtype=float) ** 2
    return float(np.sum(w2 * err) / max(float(np.sum(w2 * energy)), 1e-300))


def simulation_error(
    model, experiments: Sequence, scored: Sequence[Sequence[tuple[int, int]]], weights: np.ndarray | None = None
) -> float:
    """Normalised simulation error of ``model`` on the held-out ranges of each (mean-removed) record.

    Each record is simulated from rest over its full length (so every held-out range starts
    from a consistent state) and only the samples in ``scored[i]`` (``(start, stop)`` pairs)
    count; the error energy over the variation energy, averaged over the outputs (with
    ``weights``, the ratio of the weighted sums as in :func:`prediction_error`).
    """
    if not model.is_stable():
        return float("inf")
    num = den = 0.0
    for (u, y), ranges in zip(experiments, scored):
        yh = model.simulate(u)
        for a, b in ranges:
            e = y[a:b] - yh[a:b]
            yy = y[a:b] - y[a:b].mean(axis=0)
            num = num + np.sum(e**2, axis=0)
            den = den + np.sum(yy**2, axis=0)
    den = np.where(np.asarray(den) > 0, den, 1.0)
    val = _normalised(np.asarray(num), den, weights)
    return val if np.isfinite(val) else float("inf")
