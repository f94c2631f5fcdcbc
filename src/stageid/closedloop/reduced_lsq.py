"""SciPy's trust-region least squares on the QR-reduced problem of a tall Jacobian.

The prediction-error Jacobians are tall (``10 000 x 2n``) and :func:`scipy.optimize.least_squares`
(``method="trf"``) takes the SVD of the whole scaled Jacobian every iteration.  Everything the
``trf`` iteration uses -- ``|f|``, ``J^T f``, ``J^T J``, the column norms of ``J`` -- survives an
orthogonal transformation, and the basis may differ from point to point as long as a point's
residual and Jacobian share it.  So SciPy is handed an ``(n + 1)``-row problem: the residual
``|f| e_(n+1)`` (no Jacobian needed at trial points), and at the points it accepts the triangle
of one Householder QR ``[J | f] = Q R`` turned so that its residual column is that vector.
The same iterates as on the full problem, to rounding, at a fraction of the cost.

The same triangle gives the stop :func:`reduced_least_squares` adds to SciPy's: its last
diagonal element is the residual norm after the full Gauss-Newton step, so
``1 - R[n, n]^2 / |f|^2`` is the relative loss decrease the linearised problem still offers
(the Gauss-Newton decrement).  SciPy's ``ftol`` looks at the decrease of the step just taken,
which stays small along a narrow valley however far its floor still falls.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.linalg import lapack
from scipy.optimize import OptimizeResult, least_squares

__all__ = ["qr_reduce", "reduced_least_squares"]


def qr_reduce(J: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(J_r, |f| e_(n+1), decrement)``, ``n + 1`` rows, with ``J_r^T J_r = J^T J`` and
    ``J_r^T f_r = J^T f``; ``decrement = 1 - min_p |J p + f|^2 / |f|^2``."""
    m, n = J.shape
    W = np.empty((m, n + 1), order="F")
    W[:, :n] = J
    W[:, n] = f
    R = np.triu(lapack.dgeqrf(W, overwrite_a=1)[0][: n + 1])
    J_r, f_r = R[:, :n], R[:, n]  # row n of J_r is zero
    f_r[n] = -abs(f_r[n])  # (flipping that row's sign is orthogonal too) so that v[n] below does not cancel
    target = np.zeros(n + 1)
    target[n] = np.linalg.norm(f_r)
    decrement = float(1.0 - (f_r[n] / target[n]) ** 2) if target[n] > 0 else 0.0
    v = f_r - target  # the reflection I - 2 v v^T / v^T v takes f_r to target (equal norms)
    vv = v @ v
    if vv > 0:
        J_r = J_r - np.outer(v, (2.0 / vv) * (v @ J_r))
    return J_r, target, decrement


class _Decremented(Exception):
    """Raised inside SciPy's iteration when the Gauss-Newton decrement is below its tolerance."""


def reduced_least_squares(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    max_nfev: int,
    ftol: float = 1e-12,
    xtol: float = 1e-12,
    gtol: float = 1e-12,
    decrement_tol: float = 0.0,
) -> OptimizeResult:
    """``least_squares(fun, x0, jac=jac, method="trf", x_scale="jac", ...)`` through :func:`qr_reduce`.

    ``jac(x)`` is called only at points whose residual ``fun(x)`` was the last one evaluated.
    Needs more residuals than parameters plus one (the full problem is solved otherwise).  The
    result's ``fun`` is the reduced residual; its norm is that of the full one.

    ``decrement_tol`` adds a stop: at an accepted point whose Gauss-Newton decrement (the
    relative loss decrease the full Gauss-Newton step predicts) is below it, the iteration ends
    there with ``status = 1`` (converged), as SciPy's gradient test would.
    """
    x0 = np.asarray(x0, dtype=float)
    kwargs = dict(method="trf", x_scale="jac", max_nfev=max_nfev, ftol=ftol, xtol=xtol, gtol=gtol)
    n = x0.size
    last: dict = {"x": None, "f": fun(x0)}
    if last["f"].size <= n + 1:
        return least_squares(fun, x0, jac=jac, **kwargs)
    last["x"] = x0.copy()
    calls = {"fun": 0}

    def fun_r(x):
        calls["fun"] += 1
        if last["x"] is None or not np.array_equal(x, last["x"]):
            last["x"], last["f"] = x.copy(), fun(x)
        norm = np.linalg.norm(last["f"]) if np.all(np.isfinite(last["f"])) else np.nan
        out = np.zeros(n + 1)
        out[n] = norm
        return out

    def jac_r(x, _f=None):
        if not np.array_equal(x, last["x"]):  # SciPy asks at the point just evaluated; be safe
            fun_r(x)
        if not np.all(np.isfinite(last["f"])):
            return np.full((n + 1, n), np.nan)
        J_r, _, decrement = qr_reduce(jac(x), last["f"])
        if decrement < decrement_tol:
            raise _Decremented
        return J_r

    try:
        return least_squares(fun_r, x0, jac=jac_r, **kwargs)
    except _Decremented:
        f_r = np.zeros(n + 1)
        f_r[n] = np.linalg.norm(last["f"])
        return OptimizeResult(
            x=last["x"].copy(),
            fun=f_r,
            cost=0.5 * f_r[n] ** 2,
            nfev=calls["fun"],
            status=1,
            success=True,
            message="The Gauss-Newton decrement is below `decrement_tol`.",
        )
