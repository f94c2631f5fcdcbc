"""Order selection of the closed-loop models by an information criterion (BIC or AIC).

Every candidate order ``n`` sets all free polynomials of the structure to order ``n``
(:func:`~stageid.closedloop.polynomial.structure_orders`).  For output-error and Box-Jenkins
models the candidates are first ranked by the criterion of cheap Steiglitz-McBride estimates
(:func:`screen_orders`), and the prediction-error optimisation runs for the winner only.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.signal as ss

from .._errors import DataError, IdentificationError
from .initial import SM_ITERATIONS, steiglitz_mcbride, steiglitz_mcbride_orders
from .mode_injection import explained_residual_peaks, with_modes
from .pem import fit_pem
from .polynomial import STRUCTURES, PolynomialModel, structure_orders
from .regression import check_dt, check_moving, records

__all__ = [
    "select_order",
    "screen_orders",
    "criterion_value",
    "SCREEN_ITERATIONS",
    "SCREEN_OWN_ITERATIONS",
    "START_ITERATIONS",
    "loop_order_bound",
    "continuation_orders",
    "CONTINUATION_STEP",
    "MODES_ADDED",
]

#: Steiglitz-McBride passes of the screen pre-filtered by the largest order's ``F``, all orders at once
SCREEN_ITERATIONS = 6
#: then passes of each order with its own pre-filter
SCREEN_OWN_ITERATIONS = 1
#: own passes the selected order's PEM start adds to the screen's estimate
START_ITERATIONS = 2
#: order step of the continuation up to the largest order
CONTINUATION_STEP = 2
#: lightly damped modes added at most to a lower order's optimum to restart the largest order
MODES_ADDED = 2


def criterion_value(criterion: str, n_samples: int, loss: float, n_parameters: int) -> float:
    """``N log(V) + k log(N)`` (BIC) or ``N log(V) + 2 k`` (AIC)."""
    penalty = n_parameters * np.log(n_samples) if criterion == "bic" else 2.0 * n_parameters
    return n_samples * np.log(max(loss, 1e-300)) + penalty


def screen_orders(segs, orders: Sequence[int], nk: int, criterion: str) -> tuple[dict[int, float], dict[int, tuple]]:
    """Criterion of a Steiglitz-McBride estimate per order, and the ``F`` each estimate reached.

    :data:`SCREEN_ITERATIONS` passes pre-filtered by the largest order's ``F`` give every order's
    estimate from one QR per pass (:func:`~stageid.closedloop.initial.steiglitz_mcbride_orders`);
    then :data:`SCREEN_OWN_ITERATIONS` pass of each order with its own pre-filter, which removes
    the bias a foreign pre-filter leaves in the smaller orders.  Returns ``(scores, states)``;
    ``states[n] = (SM_ITERATIONS - START_ITERATIONS, F)`` lets the PEM start of the selected
    order run :data:`START_ITERATIONS` more own passes from there.  Orders whose regression
    fails are left out.
    """
    N = sum(s_[0].size for s_ in segs)
    scores, states = {}, {}
    for n, (_, F0) in steiglitz_mcbride_orders(segs, orders, nk, SCREEN_ITERATIONS).items():
        try:
            B, F = steiglitz_mcbride(segs, n, n, nk, n_iter=SCREEN_OWN_ITERATIONS, F0=F0)
        except IdentificationError:
            continue
        states[n] = (SM_ITERATIONS - START_ITERATIONS, F)
        bu = np.concatenate([np.zeros(nk), B])
        res = np.concatenate([yy - ss.lfilter(bu, F, uu) for uu, yy in segs])
        scores[n] = criterion_value(criterion, N, float(np.mean(res**2)), 2 * n)
    return scores, states


def select_order(
    u: object,
    y: object,
    structure: str = "oe",
    orders: Sequence[int] = tuple(range(1, 11)),
    nk: int = 1,
    dt: float = 1.0,
    criterion: str = "bic",
    max_nfev: int = 200,
    screen: bool = True,
    refine_largest: bool = False,
) -> tuple[PolynomialModel, dict[int, float]]:
    """Fit ``structure`` for each order ``n`` (all free polynomials of order ``n``) and keep the best.

    Parameters
    ----------
    u, y : array_like or lists of arrays
        As in :func:`~stageid.closedloop.pem.pem`.
    structure : {"arx", "armax", "oe", "bj"}
    orders : sequence of int
        Candidate orders ``n``: ``nb = nf = n`` for OE, ``na = nb = n`` (``nc = n``) for
        ARX/ARMAX, ``nb = nf = n`` and ``nc = nd = 2`` for BJ.
    criterion : {"bic", "aic"}
        ``N log(V) + k log(N)`` (BIC) or ``N log(V) + 2 k`` (AIC), ``k`` the number of parameters.
    screen : bool
        For OE and BJ with more than three candidates: rank the orders by the criterion of
        cheap Steiglitz-McBride estimates and run the prediction-error optimisation only for
        the winner; otherwise every order is optimised.
    refine_largest : bool
        With the screen, optimise the larger orders too, the criterion deciding after: the
        screen's estimates degrade at high orders, where a coupled loop's weak modes sit.  The
        orders from the winner (or four below the largest, if lower) are climbed in steps of
        :data:`CONTINUATION_STEP`, each optimised from the optimum below it padded with zeros
        (the same model, so the loss never rises on the way) and the largest once more from
        the optimum two and four orders below with one and two lightly damped modes added where
        the residual still follows the input (:mod:`~stageid.closedloop.mode_injection`).

    Returns
    -------
    (PolynomialModel, dict)
        The selected model and the criterion value for each order optimised.

    Raises
    ------
    DataError
        ``dt`` not a positive finite number; ragged or non-finite records.
    IdentificationError
        When no order could be fitted, the criterion is unknown, or the input is constant in
        every record (as in :func:`~stageid.closedloop.initial.arx`).

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> u = np.random.default_rng(2).standard_normal(3000)
    >>> y = ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + 1e-3 * np.random.default_rng(3).standard_normal(3000)
    >>> m, scores = select_order(u, y, "oe", orders=[1, 2, 3, 4])
    >>> m.F.size - 1
    2
    """
    if criterion not in ("bic", "aic"):
        raise IdentificationError(f"`criterion` must be 'bic' or 'aic'; got {criterion!r}.")
    if structure not in STRUCTURES:
        raise IdentificationError(f"`structure` must be one of {', '.join(STRUCTURES)}; got {structure!r}.")
    dt = check_dt(dt)
    segs = records(u, y)
    check_moving(segs, structure)
    orders = [int(n) for n in orders]
    states: dict[int, tuple] = {}
    if screen and structure in ("oe", "bj") and len(orders) > 3:
        screen_scores, states = screen_orders(segs, orders, nk, criterion)
        if screen_scores:
            winner = min(screen_scores, key=screen_scores.get)
            if refine_largest:
                return _climb(u, y, structure, winner, orders, nk, dt, criterion, max_nfev, states)
            orders = [winner]
    return _best_by_criterion(u, y, structure, orders, nk, dt, criterion, max_nfev, states)


def _best_by_criterion(u, y, structure, orders, nk, dt, criterion, max_nfev, states):
    """The prediction-error fit of each order in ``orders`` (screen states as starts); the best by the criterion."""
    scores: dict[int, float] = {}
    best: PolynomialModel | None = None
    best_score = np.inf
    last_error: Exception | None = None
    for n in orders:
        try:
            m = fit_pem(u, y, structure, structure_orders(structure, n), nk, dt, max_nfev, None, states.get(n))
        except (IdentificationError, DataError) as exc:
            last_error = exc
            continue
        score = criterion_value(criterion, m.n_samples, m.loss, m.n_parameters)
        scores[int(n)] = float(score)
        if score < best_score:
            best, best_score = m, score
    if best is None:
        raise IdentificationError(f"no {structure} model could be fitted for orders {list(orders)}: {last_error}")
    return best, scores


def continuation_orders(low: int, orders: Sequence[int]) -> list[int]:
    """The orders a continuation from ``low`` climbs: ``low``, and the largest candidate and every
    :data:`CONTINUATION_STEP`-th order below it down to ``low`` (those among the candidates)."""
    candidates = set(orders)
    top = max(candidates)
    return sorted({n for n in range(top, low, -CONTINUATION_STEP) if n in candidates} | {low})


def _climb(u, y, structure, winner, orders, nk, dt, criterion, max_nfev, states):
    """The orders from ``min(winner, top - 2 MODES_ADDED)`` up to the largest, each optimised from
    the optimum below it (zero-padded: the same model), the lowest, the screen's winner and the
    largest from their own starts too; then the largest order again from the optimum
    ``2 k`` below it with ``k`` lightly damped modes added (:func:`_with_missing_modes`); the best
    of all by the criterion.

    At the orders a coupled loop needs (about 30), an optimisation from a linear start stops in
    local minima whose loss is not even monotone in the order, while the padded optimum of the
    order below is a start the loss can only improve on (``benchmarks/RESULTS-recovery.md``, PEM).
    """
    top = max(orders)
    low = min(winner, max(min(orders), top - 2 * MODES_ADDED))
    rungs: dict[int, PolynomialModel] = {}
    current = None
    for n in sorted({winner, *continuation_orders(low, orders)}):
        own = n in (low, winner, top) or current is None
        fitted = [
            m
            for m in (
                None if current is None else _fit_or_none(u, y, structure, n, nk, dt, max_nfev, current, None),
                _fit_or_none(u, y, structure, n, nk, dt, max_nfev, None, states.get(n)) if own else None,
            )
            if m is not None
        ]
        if fitted:
            current = rungs[n] = min(fitted, key=lambda m: m.loss)
    if not rungs:
        raise IdentificationError(f"no {structure} model could be fitted for orders {list(orders)}.")
    for m in _with_missing_modes(u, y, structure, rungs, top, nk, dt, max_nfev):
        n = m.F.size - 1
        if n not in rungs or m.loss < rungs[n].loss:
            rungs[n] = m
    scores = {n: _score(m, criterion) for n, m in rungs.items()}
    return rungs[min(scores, key=scores.get)], scores


def _with_missing_modes(u, y, structure, rungs, top, nk, dt, max_nfev) -> list[PolynomialModel]:
    """For ``k = 1 .. MODES_ADDED``: the optimum of order ``top - 2 k`` with its residual's ``k``
    strongest input-explained lines added as lightly damped modes
    (:mod:`~stageid.closedloop.mode_injection`), optimised at order ``top``."""
    segs = records(u, y)
    out = []
    for k in range(1, MODES_ADDED + 1):
        base = rungs.get(top - 2 * k)
        if base is None:
            continue
        start = with_modes(base, explained_residual_peaks(base, segs, k))
        m = _fit_or_none(u, y, structure, top, nk, dt, max_nfev, start, None)
        if m is not None:
            out.append(m)
    return out


def _score(model: PolynomialModel, criterion: str) -> float:
    return float(criterion_value(criterion, model.n_samples, model.loss, model.n_parameters))


def _fit_or_none(u, y, structure, n, nk, dt, max_nfev, initial, sm_start) -> PolynomialModel | None:
    """The prediction-error fit of order ``n`` from ``initial`` (or the linear start), None when it fails."""
    try:
        return fit_pem(u, y, structure, structure_orders(structure, n), nk, dt, max_nfev, initial, sm_start)
    except (IdentificationError, DataError):
        return None


def loop_order_bound(entry_orders: dict[tuple[int, int], tuple[int, int]], controller_states: int) -> int:
    """Upper bound on the order of a closed-loop pair ``T_ij`` (eq. 15-17 for a transfer matrix).

    Every pair shares the loop's poles, whose count is the plant's McMillan degree plus the
    controller's states; the plant's degree is at most the sum of its entries' pole counts
    ``entry_orders[(i, j)] = (n_zeros, n_poles)`` (each entry realised on its own).  For the
    paper's 3x3 structure and three [2, 2] lead-lags that is 24 + 6 = 30 (a 2x2 loop: 10 + 4 = 14).
    """
    return int(sum(n_poles for _, n_poles in entry_orders.values())) + int(controller_states)
