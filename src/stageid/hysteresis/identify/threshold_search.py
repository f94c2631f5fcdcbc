"""Step 3 of the identification: the CP thresholds of the modified PI by nonlinear search.

``rc_i = c_i r_i``, ``ra_i = a_i r_i``, ``rb_i = b_i ra_i`` with ratios linear in the operator
index (``c_i = c0 + c1 t_i``, ``t_i = i/(n-1) - 1/2``, likewise ``a_i``, ``b_i``), clipped to
the orderings eq. 3 needs, the centre ``xc`` and (our extension) the monotone quadratic input
warp ``q``: eight parameters ``theta``.  Every evaluation is one weight fit of :mod:`.weights`
(the residual with the best weights for those thresholds).  A coarse grid of the mean ratios
and the warp; then either bounded Nelder-Mead from the best grid point within a budget, or
(no budget given) the best grid points settled one by one: Gauss-Newton on the projected
residual (:mod:`.threshold_polish`) to the bottom of the start's valley, then rounds of Powell's
method and a simplex until the residual stops falling.  The classical model (all ratios 1, no
warp) is among the candidates, so the result is never worse than it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .threshold_polish import polish_thresholds
from .weights import WeightProblem

__all__ = ["search_thresholds", "SearchResult", "StallStop", "merged_result"]

#: Initial simplex steps of the eight parameters (in their scaled units).
_STEPS = np.array([0.1, 0.2, 0.15, 0.3, 0.1, 0.2, 0.05, 0.05])
#: Settling: rounds of Powell's method and a fresh simplex (``SETTLE_CHUNK`` weight fits each)
#: from the best point until a round lowers the residual by less than ``SETTLE_TOLERANCE``
#: (relative), at most ``SETTLE_LIMIT`` weight fits in all.  A single budgeted simplex stalled
#: above the optimum on random modified-PI plants (benchmarks/RESULTS-recovery.md, Modified PI).
SETTLE_CHUNK = 400
SETTLE_TOLERANCE = 1e-4
SETTLE_LIMIT = 20000
#: Grid points (after the best) that are settled too: the residual over the thresholds has
#: several valleys, and the best grid point was not in the deepest on some random plants (one
#: recovery draw's deepest valley is reached from the eighth only: benchmarks/RESULTS-recovery.md).
SETTLE_STARTS = 7
#: A simplex of the settling stops on the cost: when its best residual fell by less than
#: ``STALL_TOLERANCE`` (relative) over its last ``STALL_EVALUATIONS`` weight fits, it is
#: shuffling at the bottom of its valley (the round's Powell step goes on from there).
STALL_EVALUATIONS = 100
STALL_TOLERANCE = 1e-6
#: A start whose path comes within this distance (max over the scaled parameters) of a point an
#: earlier start passed, at no lower residual, follows that start and takes its result: grid
#: points one line search apart often meet after their first Powell step.
MERGE_DISTANCE = 1e-3
#: A start that Gauss-Newton leaves more than this (relative) above the best residual of the
#: starts settled before is at the bottom of a worse valley: it is not settled further.
SETTLE_MARGIN = 0.01
#: The first starts are settled whatever Gauss-Newton left: on measured records (not of the
#: class) it can stop on a kink far above the bottom that Powell and the simplex reach.
SETTLE_ALWAYS = 4


@dataclass(frozen=True)
class SearchResult:
    theta: np.ndarray
    n_evaluations: int
    success: bool
    message: str


@dataclass
class _Objective:
    """The residual of the weight fit as a function of the free parameters (scaled), cached."""

    problem: WeightProblem
    kinds: list[str]
    theta0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    scale: np.ndarray
    active: np.ndarray
    count: int = 0
    cache: dict = field(default_factory=dict)

    def __call__(self, v: np.ndarray) -> float:
        th = np.array(self.theta0, dtype=float)
        th[self.active] = np.asarray(v) * self.scale[self.active]
        th = np.clip(th, self.lower, self.upper)
        key = tuple(np.round(th, 12))
        if key not in self.cache:
            self.count += 1
            self.cache[key] = self.problem.solve(th, self.kinds, classical=False)[0]
        return self.cache[key]

    def at(self, theta: np.ndarray) -> float:
        return self(theta[self.active] / self.scale[self.active])


def _grid(objective: _Objective, centre: float, input_warp: bool) -> list[tuple[float, np.ndarray]]:
    """The residual at every point of the coarse grid of mean ratios (and warps), best first."""
    grid = []
    for q in (-0.2, 0.0, 0.2) if input_warp else (0.0,):
        for c0 in (0.2, 0.5, 0.8, 1.0):
            for a0 in (0.7, 1.0, 1.4, 2.0):
                for b0 in (0.4, 0.7, 1.0):
                    th = np.array([c0, 0.0, a0, 0.0, b0, 0.0, centre, q])
                    grid.append((objective.at(th), th))
    grid.sort(key=lambda item: item[0])
    return grid


class StallStop:
    """Nelder-Mead callback: StopIteration when the best residual fell by less than
    ``STALL_TOLERANCE`` (relative) over the last ``STALL_EVALUATIONS`` weight fits."""

    def __init__(self, objective: _Objective) -> None:
        self.objective = objective
        self.history: list[tuple[int, float]] = []

    def __call__(self, intermediate_result) -> None:
        count, f = self.objective.count, float(intermediate_result.fun)
        self.history.append((count, f))
        while len(self.history) > 1 and self.history[1][0] <= count - STALL_EVALUATIONS:
            self.history.pop(0)
        start_count, start_f = self.history[0]
        if count - start_count >= STALL_EVALUATIONS and f > start_f * (1.0 - STALL_TOLERANCE):
            raise StopIteration


def _descend(
    objective: _Objective,
    th_start: np.ndarray,
    f_start: float,
    free: np.ndarray,
    maxfev: int,
    method: str = "Nelder-Mead",
    stall: bool = False,
) -> tuple[float, np.ndarray, bool]:
    """Bounded Nelder-Mead (or Powell) over the parameters ``free`` (indices into theta) from
    ``th_start``; with ``stall``, a simplex that stops lowering the residual ends early
    (:class:`StallStop`)."""
    from scipy.optimize import minimize

    scale, lower, upper = objective.scale, objective.lower, objective.upper
    base = np.array(th_start, dtype=float)

    def sub(v: np.ndarray) -> float:
        th = base.copy()
        th[free] = np.asarray(v) * scale[free]
        return objective.at(th)

    x0 = base[free] / scale[free]
    lb, ub = lower[free] / scale[free], upper[free] / scale[free]
    options = {"maxfev": maxfev, "xtol": 1e-6}
    if method == "Nelder-Mead":
        steps = _STEPS[free]
        k = free.size
        simplex = np.vstack(
            [x0] + [x0 + np.eye(k)[i] * steps[i] * (1 if x0[i] + steps[i] <= ub[i] else -1) for i in range(k)]
        )
        options = {"maxfev": maxfev, "initial_simplex": simplex, "xatol": 1e-5, "fatol": 1e-10 * f_start}
    callback = StallStop(objective) if stall and method == "Nelder-Mead" else None
    res = minimize(sub, x0, method=method, bounds=list(zip(lb, ub)), options=options, callback=callback)
    th = base.copy()
    th[free] = res.x * scale[free]
    return float(res.fun), np.clip(th, lower, upper), res.nfev < maxfev


def _settle(
    objective: _Objective, th: np.ndarray, f: float, free: np.ndarray, paths: list, bound: float = np.inf
) -> tuple[float, np.ndarray, bool]:
    """Gauss-Newton on the projected residual from ``th`` (:func:`.polish_thresholds`), then
    Powell's method and a fresh simplex in turn until a round lowers the residual by less than
    ``SETTLE_TOLERANCE``; False when ``SETTLE_LIMIT`` weight fits ran out first.  Powell's line
    searches get past ridges where a simplex of fixed shape stalls.  A start that Gauss-Newton
    leaves more than ``SETTLE_MARGIN`` above ``bound`` (the best start settled before) ends there.

    ``paths`` holds ``(points passed, result)`` of the starts settled before (this one's is
    appended): a start that meets an earlier path (:func:`merged_result`) ends with that path's result.
    """
    passed: list[tuple[np.ndarray, float]] = []
    th_gn, n_fits = polish_thresholds(
        objective.problem, objective.kinds, th, free, (objective.lower, objective.upper, objective.scale)
    )
    objective.count += n_fits
    f_gn = objective.at(th_gn)
    if f_gn < f:
        f, th = f_gn, th_gn
    result = merged_result(paths, th, f, objective.scale)
    if result is None and f > bound * (1.0 + SETTLE_MARGIN):
        result = (f, th, True)  # the bottom of a valley above one already settled
    if result is None:
        passed.append((th.copy(), f))
    while result is None and objective.count < SETTLE_LIMIT:
        f_round = f
        for method in ("Powell", "Nelder-Mead"):
            budget = min(SETTLE_CHUNK, SETTLE_LIMIT - objective.count)
            f_new, th_new, _ = _descend(objective, th, f, free, budget, method, stall=True)
            if f_new < f:
                f, th = f_new, th_new
            result = merged_result(paths, th, f, objective.scale)
            if result is not None:
                break
            passed.append((th.copy(), f))
        if result is None and not f < f_round * (1.0 - SETTLE_TOLERANCE):
            result = (f, th, True)
    result = (f, th, False) if result is None else result
    paths.append((passed, result))
    return result


def merged_result(paths: list, th: np.ndarray, f: float, scale: np.ndarray) -> tuple | None:
    """The result of an earlier start (``paths``: ``(points passed, result)``, a point being
    ``(theta, residual)``) that passed within ``MERGE_DISTANCE`` of ``th`` (in units of
    ``scale``) at a residual no higher than ``f``; None when no path was met."""
    for passed, result in paths:
        for th_passed, f_passed in passed:
            if f_passed <= f and np.max(np.abs((th - th_passed) / scale)) < MERGE_DISTANCE:
                return result
    return None


def _settle_starts(objective: _Objective, starts: list[tuple[float, np.ndarray]]) -> tuple[float, np.ndarray, bool]:
    """Every start settled (:func:`_settle`), each after the first ``SETTLE_ALWAYS`` bounded by
    the best of those before; the best."""
    paths: list = []
    settled: list[tuple[float, np.ndarray, bool]] = []
    for k, (f, th) in enumerate(starts):
        bound = min((item[0] for item in settled), default=np.inf) if k >= SETTLE_ALWAYS else np.inf
        settled.append(_settle(objective, th, f, objective.active, paths, bound))
    return min(settled, key=lambda item: item[0])


def _budgeted(
    objective: _Objective, grid: list, best: tuple[float, np.ndarray], budget: int, input_warp: bool
) -> tuple[float, np.ndarray, bool]:
    """Steps 1-2 of :func:`search_thresholds` from the best start: the simplexes within ``budget``."""
    best_f, best_th = best
    active = objective.active
    remaining = budget - objective.count
    success = remaining > 20
    if success:
        f_new, th_new, success = _descend(
            objective, best_th, best_f, active, remaining // 2 if input_warp else remaining
        )
        if f_new < best_f:
            best_f, best_th = f_new, th_new
    if input_warp:
        f0, th0 = min(((f, th) for f, th in grid if th[7] == 0.0), key=lambda item: item[0])
        if budget - objective.count > 40:
            f0, th0, _ = _descend(objective, th0, f0, active[active != 7], (budget - objective.count) // 2)
            f_new, th_new, converged = _descend(objective, th0, f0, active, budget - objective.count)
            success = success and converged
            for f_c, th_c in ((f0, th0), (f_new, th_new)):
                if f_c < best_f:
                    best_f, best_th = f_c, th_c
        else:
            success = False
    return best_f, best_th, success


def search_thresholds(
    problem: WeightProblem,
    theta0: np.ndarray,
    kinds: list[str],
    R: float,
    lo: float,
    hi: float,
    input_warp: bool,
    budget: int,
    settle: bool = False,
) -> SearchResult:
    """Thresholds of the modified PI with the least residual, at most ``budget`` weight fits.

    ``theta0`` is the classical model; ``R`` the half range of the thresholds; ``(lo, hi)``
    the input range (the centre moves within its middle half).

    Without ``settle`` (a budget given):

    1. the simplex on every parameter from the best grid point, with half the budget left;
    2. with the warp, the other half chains two simplexes: the best unwarped grid point
       searched without the warp, then the warp released from there, so a warped fit cannot
       end above the unwarped optimum the search finds (a plain 8-parameter simplex from
       warped grid points stalled above it on asymmetric Bouc-Wen data).

    With ``settle`` (no budget): the best point and the next ``SETTLE_STARTS`` grid points,
    each settled (:func:`_settle`: Gauss-Newton, then rounds until the residual settles).
    """
    centre = 0.5 * (lo + hi)
    qmax = 0.4 if input_warp else 0.0
    lower = np.array([0.0, -1.0, 0.05, -2.0, 0.0, -1.0, centre - 0.25 * (hi - lo), -qmax])
    upper = np.array([1.0, 1.0, 3.0, 2.0, 1.0, 1.0, centre + 0.25 * (hi - lo), qmax])
    scale = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, R, 1.0])
    active = np.flatnonzero(upper > lower)
    objective = _Objective(problem, kinds, theta0, lower, upper, scale, active)
    classical = np.array(theta0, dtype=float)
    f_classical = objective.at(classical)
    grid = _grid(objective, centre, input_warp)
    best_f, best_th = grid[0]
    if f_classical < best_f:
        best_f, best_th = f_classical, classical
    if settle:  # the residual has several valleys: the best point and the next grid points settled
        best_f, best_th, success = _settle_starts(objective, [(best_f, best_th), *grid[1 : 1 + SETTLE_STARTS]])
    else:
        best_f, best_th, success = _budgeted(objective, grid, (best_f, best_th), budget, input_warp)
    message = (
        f"modified PI: {objective.count} weight fits in the threshold search; RMS residual "
        f"{np.sqrt(best_f / max(f_classical, 1e-300)):.3g} of the classical start's."
    )
    return SearchResult(best_th, objective.count, success, message)
