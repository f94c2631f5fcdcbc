"""Step 3, refined: the CP thresholds by Gauss-Newton on the projected residual.

With the thresholds ``theta`` fixed, the weights are the solution of a linear least-squares
problem (:mod:`.weights`); the residual at those weights, ``e(theta)``, is the variable-projection
residual, and its sum of squares is the cost the threshold search minimises.  Between the
samples where an operator changes branch, every operator output is affine in its thresholds
(eq. 3), so ``e`` is piecewise smooth in ``theta`` with kinks too small to matter at the scale of
a finite difference: a trust-region Gauss-Newton (``scipy.optimize.least_squares``) on ``e`` with
a finite-difference Jacobian reaches the bottom of a valley in a few dozen iterations, where a
simplex over the cost alone needs hundreds of weight fits (Golub & Pereyra 1973: the projected
functional has the same minimisers as the full one).
"""

from __future__ import annotations

import numpy as np

from .weights import WeightProblem

__all__ = ["projected_residuals", "polish_thresholds"]

#: Relative finite-difference step of the Jacobian: large enough that the kinks where one sample
#: crosses a branch point are averaged over, small beside the valleys' width.
DIFF_STEP = 1e-6
#: Function evaluations (Jacobian columns not counted) of one polish.
MAX_EVALUATIONS = 40


def projected_residuals(problem: WeightProblem, theta: np.ndarray, kinds: list[str]) -> np.ndarray:
    """Residual rows of all records at the best weights (and offsets, creep weights) for
    ``theta``: ``y - Z w - offset`` (minus the creep lags' part when the problem has them)."""
    if problem.lags is None:
        _, w, offsets = problem.solve(theta, kinds, classical=False)
        creep = None
    else:
        _, w, offsets, creep = problem.solve_creep(theta, kinds, classical=False)
    from .. import kernels  # numba: imported on first use

    r, rc, ra, rb, _ = problem.thresholds(theta, False)
    parts, start = [], 0
    for j, ((x, z0), rows, offset) in enumerate(
        zip(problem.operator_inputs(theta, kinds, False), problem.rows, offsets)
    ):
        fit = kernels.cp_sum(x, r, rc, ra, rb, w, z0)[0][rows] + offset
        if creep is not None:
            fit = fit + problem.lags[j] @ creep
        parts.append(problem.y[start : start + rows.size] - fit)
        start += rows.size
    return np.concatenate(parts)


def polish_thresholds(
    problem: WeightProblem,
    kinds: list[str],
    theta: np.ndarray,
    free: np.ndarray,
    box: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, int]:
    """``theta`` moved downhill by Gauss-Newton over the parameters ``free`` (indices into
    theta) within ``box = (lower, upper, scale)``; also the number of weight fits it took."""
    from scipy.optimize import least_squares

    lower, upper, scale = box
    base = np.clip(np.array(theta, dtype=float), lower, upper)
    count = 0

    def full(v: np.ndarray) -> np.ndarray:
        th = base.copy()
        th[free] = v * scale[free]
        return np.clip(th, lower, upper)

    def residuals(v: np.ndarray) -> np.ndarray:
        nonlocal count
        count += 1
        return projected_residuals(problem, full(v), kinds)

    lb, ub = lower[free] / scale[free], upper[free] / scale[free]
    sol = least_squares(
        residuals,
        base[free] / scale[free],
        bounds=(lb, ub),
        method="trf",
        diff_step=DIFF_STEP,
        max_nfev=MAX_EVALUATIONS,
        xtol=1e-10,
        ftol=1e-12,
    )
    return full(sol.x), count
