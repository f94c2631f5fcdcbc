"""Prediction-error identification of discrete polynomial models (Shakir & Kim, eq. 12-14).

The parameters of a structure of :mod:`~stageid.closedloop.polynomial` minimise eq. 13,
``V_N = sum e(t)^2``, with the prediction error of eq. 14, ``e = D/C (A y - B/F u)``, by
:func:`~stageid.closedloop.reduced_lsq.reduced_least_squares` (SciPy's trust-region ``trf`` on the
QR-reduced problem) with the analytic Jacobian,
started from the linear estimates of :mod:`~stageid.closedloop.initial`, and stopped once the
Gauss-Newton step offers less than a hundredth of the estimate's statistical excess loss
(:func:`decrement_tol`).  The predictor is
kept stable: roots of ``C`` and ``F`` that leave the unit circle are reflected into it
(Ljung 1999, sec. 10.5) before the loss is evaluated.

Order selection by BIC/AIC lives in :mod:`~stageid.closedloop.order_selection`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.signal as ss

from .._errors import DataError, IdentificationError
from .initial import arx, start
from .polynomial import PolynomialModel, check_orders, pack, residual_parts, stabilize, unpack
from .reduced_lsq import reduced_least_squares
from .regression import check_dt, check_moving, records, regressor

__all__ = ["pem", "fit_pem", "jacobian", "decrement_tol", "STOP_FRACTION"]


#: fraction of the statistical excess loss ``d / N`` that a Gauss-Newton step must still offer
STOP_FRACTION = 0.01


def decrement_tol(n_parameters: int, n_samples: int) -> float:
    """Relative Gauss-Newton decrement below which the optimiser stops: ``STOP_FRACTION * d / N``.

    The parameters estimated from ``N`` samples with ``d`` parameters are uncertain by an amount
    worth ``d / N`` of the loss: on fresh data their expected loss exceeds the true parameters'
    by that fraction (Akaike's FPE; Ljung 1999, ch. 16).  Once the linearised problem offers
    less than a hundredth of that, the remaining steps move the model far less than its own
    standard error.  The decrement is the whole decrease the full Gauss-Newton step predicts, so
    unlike the decrease of one trust-region step it stays large along a narrow valley.
    """
    return STOP_FRACTION * n_parameters / max(n_samples, 1)


def pem(
    u: object,
    y: object,
    structure: str = "oe",
    orders: Mapping[str, int] | None = None,
    nk: int = 1,
    dt: float = 1.0,
    max_nfev: int = 200,
    initial: PolynomialModel | None = None,
) -> PolynomialModel:
    """Prediction-error estimate of a polynomial model (eq. 12-14 of Shakir & Kim).

    Parameters
    ----------
    u, y : array_like of shape (n_samples,), or lists of such arrays
        Input (the reference ``r`` in closed-loop use) and output records.  Several
        records are fitted jointly, each simulated from rest.
    structure : {"arx", "armax", "oe", "bj"}
        Model structure (:mod:`stageid.closedloop.polynomial`).
    orders : dict
        Orders of the free polynomials, e.g. ``{"nb": 4, "nf": 4}`` for OE,
        ``{"na": 2, "nb": 2, "nc": 2}`` for ARMAX, ``{"nb", "nc", "nd", "nf"}`` for BJ.
    nk : int
        Input delay in samples (1 for a sampled strictly proper loop).
    dt : float
        Sample time in seconds, finite and > 0, stored in the result.
    max_nfev : int
        Limit on loss evaluations of the optimiser.
    initial : PolynomialModel, optional
        Start from these polynomials instead of the ARX / Steiglitz-McBride estimate.

    Returns
    -------
    PolynomialModel
        With ``loss`` = mean squared prediction error; ``converged`` False when the
        optimiser stopped on ``max_nfev``.

    Raises
    ------
    DataError
        ``dt`` not a positive finite number; ragged, non-finite or too short records.
    IdentificationError
        Unknown structure, bad orders, or data that do not excite the model (among them an
        input that is constant in every record, refused as in :func:`arx`).

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(2000)
    >>> y = ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + 0.01 * rng.standard_normal(2000)
    >>> m = pem(u, y, "oe", {"nb": 2, "nf": 2})
    >>> np.allclose(m.F, [1, -1.2, 0.5], atol=0.01)
    True
    """
    return fit_pem(u, y, structure, orders, nk, dt, max_nfev, initial)


def fit_pem(u, y, structure, orders, nk, dt, max_nfev=200, initial=None, sm_start=None) -> PolynomialModel:
    """:func:`pem` with one more option for the order screen.

    ``sm_start = (k, F)``: the Steiglitz-McBride start counts ``k`` passes done and continues
    from ``F`` (the order screen passes its estimate of the order, so only the remaining passes
    are run).
    """
    orders = check_orders(structure, dict(orders or {}), nk)
    dt = check_dt(dt)
    segs = records(u, y)
    n_total = sum(s[0].size for s in segs)
    n_par = sum(orders.values())
    if n_total < 3 * n_par + 10:
        raise DataError(
            f"a {structure} model with {n_par} parameters needs at least {3 * n_par + 10} samples; got {n_total}."
        )
    check_moving(segs, structure)
    if structure == "arx" and initial is None:  # linear: the least-squares estimate is the optimum
        return arx([s[0] for s in segs], [s[1] for s in segs], orders["na"], orders["nb"], nk, dt)
    polys = start(segs, structure, orders, nk, dt, initial, sm_start)
    return _minimise(segs, structure, orders, nk, dt, max_nfev, polys)


def _minimise(segs, structure, orders, nk, dt, max_nfev, polys) -> PolynomialModel:
    """Minimise eq. 13 from ``polys = (A, B, C, D, F)`` with the analytic Jacobian."""
    A, B, C, D, F = polys
    # scale the output so that the loss is O(1): least_squares tolerances are absolute-ish
    yscale = max(np.sqrt(np.mean(np.concatenate([s[1] for s in segs]) ** 2)), 1e-300)
    segs_s = [(uu, yy / yscale) for uu, yy in segs]
    fun, jac, parts = _loss_functions(segs_s, orders, nk)
    stop = decrement_tol(sum(orders.values()), sum(uu.size for uu, _ in segs))
    try:
        sol = reduced_least_squares(
            fun, jac, pack(A, B / yscale, C, D, F), max_nfev, ftol=1e-12, xtol=1e-12, gtol=1e-12, decrement_tol=stop
        )
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise IdentificationError(f"the {structure} prediction-error optimisation failed: {exc}") from None
    A, B, C, D, F = parts(sol.x)
    res = fun(pack(A, B, C, D, F)) * yscale
    if not np.all(np.isfinite(res)):
        raise IdentificationError(f"the {structure} prediction-error optimisation diverged (non-finite residuals).")
    loss = float(np.mean(res**2))
    return PolynomialModel(
        A, B * yscale, C, D, F, int(nk), dt, structure, loss, res.size, int(sol.nfev), bool(sol.status > 0)
    )


def _loss_functions(segs, orders, nk):
    """``(fun, jac, parts)`` of the optimiser: residual vector, Jacobian and stabilised polynomials.

    The optimiser asks for the Jacobian at the point whose residual it has just evaluated:
    that point's polynomials and filtered signals are kept rather than recomputed.
    """
    last: dict = {}
    n_rows = sum(uu.size for uu, _ in segs)
    n_par = sum(orders.values())

    def evaluate(theta):
        key = np.asarray(theta, dtype=float).tobytes()
        if last.get("key") != key:
            A_, B_, C_, D_, F_ = unpack(theta, orders)
            polys = (A_, B_, stabilize(C_), D_, stabilize(F_))
            last.update(key=key, polys=polys, signals=[residual_parts(*polys, nk, uu, yy) for uu, yy in segs])
        return last["polys"], last["signals"]

    def fun(theta):
        return np.concatenate([sig[2] for sig in evaluate(theta)[1]])

    def jac(theta):
        polys, signals = evaluate(theta)
        J = np.empty((n_rows, n_par), order="F")  # column fills contiguous, as the QR wants it
        r0 = 0
        for (uu, yy), sig in zip(segs, signals):
            jacobian(*polys, nk, orders, uu, yy, parts=sig, out=J[r0 : r0 + uu.size])
            r0 += uu.size
        return J

    return fun, jac, lambda theta: evaluate(theta)[0]


def jacobian(A, B, C, D, F, nk, orders, u, y, parts=None, out=None) -> np.ndarray:
    """``d e / d theta`` for one record, shape (n, n_par); ``parts`` = ``residual_parts(...)`` if known.

    With ``out`` (a (n, n_par) view) the columns are written there and ``out`` is returned.
    """
    yu, w, e = residual_parts(A, B, C, D, F, nk, u, y) if parts is None else parts
    blocks = []
    if orders["na"]:
        blocks.append((ss.lfilter(D, C, y), orders["na"], 1, False))
    DCF = np.convolve(C, F)
    if orders["nb"]:
        blocks.append((ss.lfilter(D, DCF, u), orders["nb"], nk, True))
    if orders["nc"]:
        blocks.append((ss.lfilter([1.0], C, e), orders["nc"], 1, True))
    if orders["nd"]:
        blocks.append((ss.lfilter([1.0], C, w), orders["nd"], 1, False))
    if orders["nf"]:
        blocks.append((ss.lfilter(D, DCF, yu), orders["nf"], 1, False))
    return regressor([blocks], u.size, out=out)
