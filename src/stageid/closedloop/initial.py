"""Linear estimates that start the prediction-error search: ARX, Steiglitz-McBride, Hannan-Rissanen.

* ARX (least squares) is exact for ``arx`` and the start of ``armax``;
* Steiglitz-McBride (ARX on data pre-filtered by the current ``1/F``, an instrumental-variable
  like iteration) starts ``oe`` and ``bj``, and ranks orders cheaply in
  :func:`~stageid.closedloop.order_selection.select_order`;
* Hannan-Rissanen (a long AR model, then one linear regression) starts the ``C/D`` noise
  model of ``bj``.

:func:`start` picks the estimate for a structure by name.
"""

from __future__ import annotations

import numpy as np
import scipy.signal as ss

from .._errors import IdentificationError
from .polynomial import PolynomialModel, check_orders, fit_length, residual, stabilize
from .regression import (
    check_dt,
    check_moving,
    fill_shifted,
    lstsq,
    lstsq_qr,
    prefix_lstsq,
    records,
    regressor,
    shifted,
)

__all__ = ["arx", "steiglitz_mcbride", "steiglitz_mcbride_orders", "hannan_rissanen", "start", "SM_ITERATIONS"]

#: Steiglitz-McBride passes of a PEM start
SM_ITERATIONS = 8


def arx(u: object, y: object, na: int, nb: int, nk: int = 1, dt: float = 1.0) -> PolynomialModel:
    """Least-squares ARX estimate ``A y = B u(t - nk) + e``.

    Parameters
    ----------
    u, y : array_like of shape (n_samples,), or lists of such arrays (several records)
    na, nb : int
        Orders of ``A`` (poles) and number of ``B`` coefficients.
    nk : int
        Input delay in samples.
    dt : float
        Sample time in seconds, finite and > 0 (stored in the model).

    Returns
    -------
    PolynomialModel

    Raises
    ------
    DataError
        When ``dt`` is not a positive finite number, or the records are ragged or not finite.
    IdentificationError
        When the input does not move (is constant, zero range) in any record, or the
        regression is rank deficient (input not persistently exciting).  A constant input is
        refused, not warned about, as :meth:`stageid.subspace.HankelMAP.fit` refuses data in
        which no input moves.

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> u = np.random.default_rng(0).standard_normal(500)
    >>> y = ss.lfilter([0, 0.5], [1, -0.8], u)
    >>> m = arx(u, y, na=1, nb=1)
    >>> np.round(m.A, 6).tolist(), np.round(m.B, 6).tolist()
    ([1.0, -0.8], [0.5])
    """
    dt = check_dt(dt)
    segs = records(u, y)
    check_orders("arx", {"na": na, "nb": nb}, nk)
    check_moving(segs, "arx")
    rows, rhs = [], []
    for uu, yy in segs:
        rows.append(np.hstack([-shifted(yy, na, 1), shifted(uu, nb, nk)]))
        rhs.append(yy)
    theta = lstsq(np.vstack(rows), np.concatenate(rhs), "ARX")
    A = np.concatenate([[1.0], theta[:na]])
    B = theta[na:]
    one = np.ones(1)
    res = np.concatenate([residual(A, B, one, one, one, nk, uu, yy) for uu, yy in segs])
    return PolynomialModel(A, B, one, one, one, int(nk), dt, "arx", float(np.mean(res**2)), res.size)


def steiglitz_mcbride(
    segs, nb: int, nf: int, nk: int, n_iter: int = SM_ITERATIONS, F0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Output-error estimate ``(B, F)``: ARX on data pre-filtered by the current ``1/F``, ``n_iter`` times.

    ``F0`` (default 1) is the ``F`` to start from: passing the ``F`` that ``k`` iterations
    returned and ``n_iter - k`` continues them exactly.
    """
    F = np.ones(1) if F0 is None else F0
    B = np.zeros(nb)
    rows = sum(uu.size for uu, _ in segs)
    # regressor and right-hand side side by side, column-major: one Householder QR solves it
    W = np.empty((rows, nf + nb + 1), order="F")
    for _ in range(n_iter):
        blocks, r0 = [], 0
        for uu, yy in segs:
            uf = ss.lfilter([1.0], F, uu)
            yf = ss.lfilter([1.0], F, yy)
            blocks.append([(yf, nf, 1, True), (uf, nb, nk, False)])
            W[r0 : r0 + yy.size, nf + nb] = yf
            r0 += yy.size
        regressor(blocks, rows, out=W[:, : nf + nb])
        theta = lstsq_qr(W, "Steiglitz-McBride", strict=False)
        F = stabilize(np.concatenate([[1.0], theta[:nf]]))
        B = theta[nf:]
    return B, F


def steiglitz_mcbride_orders(segs, orders, nk: int, n_iter: int) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Output-error estimates ``{n: (B, F)}`` (``nb = nf = n``) of every order, one least squares per pass.

    The passes are those of :func:`steiglitz_mcbride` for the largest order; each smaller order
    is estimated from the same pre-filtered data.  The lags are interleaved
    (``-yf(t-1), uf(t-nk), -yf(t-2), uf(t-nk-1), ...``), so order ``n``'s regressor is the leading
    ``2n`` columns and one Householder QR per pass gives every order
    (:func:`~stageid.closedloop.regression.prefix_lstsq`), as an ARX order scan does.  Orders whose
    regression fails are left out; the next pre-filter is the largest remaining order's ``F``.
    """
    nmax = max(orders)
    rows = sum(uu.size for uu, _ in segs)
    F = np.ones(1)
    theta: dict[int, np.ndarray] = {}
    sizes = sorted({2 * n for n in orders}, reverse=True)
    W = np.empty((rows, 2 * nmax + 1), order="F")  # refilled every pass (the QR overwrites it)
    for it in range(n_iter):
        r0 = 0
        for uu, yy in segs:
            n_ = yy.size
            yf = ss.lfilter([1.0], F, yy)
            uf = ss.lfilter([1.0], F, uu)
            for k in range(nmax):
                fill_shifted(W[r0 : r0 + n_, 2 * k : 2 * k + 1], yf, 1 + k, negate=True)
                fill_shifted(W[r0 : r0 + n_, 2 * k + 1 : 2 * k + 2], uf, nk + k)
            W[r0 : r0 + n_, 2 * nmax] = yf
            r0 += n_
        # until the last pass only the pre-filter, the largest order that solves, is needed
        last = it == n_iter - 1
        theta = prefix_lstsq(W, sizes, "Steiglitz-McBride", first_only=not last)
        if not theta:
            return {}
        F = stabilize(np.concatenate([[1.0], theta[max(theta)][0::2]]))
    return {k // 2: (theta[k][1::2], stabilize(np.concatenate([[1.0], theta[k][0::2]]))) for k in sorted(theta)}


def hannan_rissanen(w: list[np.ndarray], nc: int, nd: int) -> tuple[np.ndarray, np.ndarray]:
    """ARMA ``D w = C e`` start values ``(C, D)``: a long AR model gives ``e``, then one regression.

    Falls back to ``C = D = 1`` when either regression is singular.
    """
    flat = np.concatenate([[1.0], np.zeros(nc)]), np.concatenate([[1.0], np.zeros(nd)])
    n_ar = max(20, 3 * (nc + nd))
    try:
        a = lstsq(np.vstack([-shifted(wk, n_ar, 1) for wk in w]), np.concatenate(w), "noise AR", strict=False)
    except IdentificationError:
        return flat
    rows, rhs = [], []
    for wk in w:
        e = ss.lfilter(np.concatenate([[1.0], a]), [1.0], wk)
        rows.append(np.hstack([-shifted(wk, nd, 1), shifted(e, nc, 1)]))
        rhs.append(wk - e)
    try:
        th = lstsq(np.vstack(rows), np.concatenate(rhs), "noise ARMA", strict=False)
    except IdentificationError:
        return flat
    D = stabilize(np.concatenate([[1.0], th[:nd]]))
    C = stabilize(np.concatenate([[1.0], th[nd:]]))
    return C, D


def _from_model(segs, orders, nk, dt, initial, sm_start):
    """The polynomials of a given model, cut or padded to the orders."""
    A, B, C, D, F = (np.asarray(p, float) for p in (initial.A, initial.B, initial.C, initial.D, initial.F))
    return (
        fit_length(A, orders["na"] + 1),
        fit_length(B, orders["nb"]),
        fit_length(C, orders["nc"] + 1),
        fit_length(D, orders["nd"] + 1),
        fit_length(F, orders["nf"] + 1),
    )


def _from_arx(segs, orders, nk, dt, initial, sm_start):
    """ARX ``A, B``; a flat ``C`` (ARMAX)."""
    m0 = arx([s[0] for s in segs], [s[1] for s in segs], orders["na"], orders["nb"], nk, dt)
    return m0.A, m0.B, np.concatenate([[1.0], np.zeros(orders["nc"])]), np.ones(1), np.ones(1)


def _from_steiglitz_mcbride(segs, orders, nk, dt, initial, sm_start):
    """Steiglitz-McBride ``B, F`` (continued from ``sm_start = (k, F)`` when given); BJ noise by Hannan-Rissanen."""
    if sm_start is not None and 0 < sm_start[0] < SM_ITERATIONS:
        k, F0 = sm_start
        B, F = steiglitz_mcbride(segs, orders["nb"], orders["nf"], nk, n_iter=SM_ITERATIONS - k, F0=F0)
    else:
        B, F = steiglitz_mcbride(segs, orders["nb"], orders["nf"], nk)
    C = np.concatenate([[1.0], np.zeros(orders["nc"])])
    D = np.concatenate([[1.0], np.zeros(orders["nd"])])
    if orders["nc"] or orders["nd"]:
        bu = np.concatenate([np.zeros(nk), B])
        C, D = hannan_rissanen([yy - ss.lfilter(bu, F, uu) for uu, yy in segs], orders["nc"], orders["nd"])
    return np.ones(1), B, C, D, F


_STARTS = {"arx": _from_arx, "armax": _from_arx, "oe": _from_steiglitz_mcbride, "bj": _from_steiglitz_mcbride}


def start(segs, structure, orders, nk, dt, initial=None, sm_start=None):
    """Start polynomials ``(A, B, C, D, F)`` for ``structure``: the given model, else the linear estimate.

    ``sm_start = (k, F)`` says ``k`` Steiglitz-McBride passes are done, ending at ``F`` (the
    order screen of :func:`~stageid.closedloop.order_selection.select_order`): the start runs
    the remaining ``SM_ITERATIONS - k`` from there.
    """
    make = _from_model if initial is not None else _STARTS[structure]
    return make(segs, orders, nk, dt, initial, sm_start)
