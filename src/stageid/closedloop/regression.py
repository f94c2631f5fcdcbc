"""Records and linear regressions shared by the polynomial fits of Shakir & Kim (eq. 12-14).

Every estimate of :mod:`stageid.closedloop` is built from lagged copies of a signal
(``x(t - start - k)``), stacked record by record, and solved by least squares with unit-norm
columns.  These helpers are public inside the package: the ARX, Steiglitz-McBride and
Hannan-Rissanen starts, the PEM Jacobian and the naive direct baseline all use them.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy.linalg import lapack

from .._errors import DataError, IdentificationError

__all__ = [
    "records",
    "check_dt",
    "check_moving",
    "shifted",
    "fill_shifted",
    "regressor",
    "lstsq",
    "lstsq_qr",
    "prefix_lstsq",
    "svd_solve",
]


def records(u: object, y: object) -> list[tuple[np.ndarray, np.ndarray]]:
    """Accept one record (1-D arrays) or a list of records; return ``[(u, y), ...]`` copies.

    Raises
    ------
    DataError
        When the records are ragged, of unequal count, or not finite.
    """
    if isinstance(u, (list, tuple)) and len(u) and np.ndim(u[0]) >= 1 and not np.isscalar(u[0]):
        us, ys = list(u), list(y)  # type: ignore[arg-type]
    else:
        us, ys = [u], [y]
    if len(us) != len(ys):
        raise DataError(f"inputs and outputs must come in the same number of records; got {len(us)} and {len(ys)}.")
    out = []
    for k, (uk, yk) in enumerate(zip(us, ys)):
        ua = np.array(uk, dtype=float).reshape(-1)
        ya = np.array(yk, dtype=float).reshape(-1)
        if ua.size != ya.size:
            raise DataError(f"record {k}: input and output must have the same length; got {ua.size} and {ya.size}.")
        if not (np.all(np.isfinite(ua)) and np.all(np.isfinite(ya))):
            raise DataError(f"record {k}: input and output must be finite (no NaN/inf).")
        out.append((ua, ya))
    return out


def check_dt(dt: object) -> float:
    """``dt`` as a float, or DataError unless it is a finite number of seconds > 0."""
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not (np.isfinite(float(dt)) and float(dt) > 0):
        raise DataError(f"`dt` must be a positive, finite number of seconds; got {dt!r}.")
    return float(dt)


def check_moving(segs: list[tuple[np.ndarray, np.ndarray]], structure: str) -> None:
    """IdentificationError when the input is constant (zero range) in every record.

    Refused rather than warned about, as :meth:`stageid.subspace.HankelMAP.fit` refuses data in
    which no input moves: a constant input is no step to learn from, and the regression would
    return a model fitted to the record's start-up transient alone.
    """
    if all(uu.size == 0 or np.ptp(uu) == 0 for uu, _ in segs):
        levels = sorted({float(uu[0]) for uu, _ in segs if uu.size})
        level = f"constant at {levels[0]:g}" if len(levels) == 1 else "constant"
        raise IdentificationError(
            f"the input must move in at least one record to identify the {structure} model; got an input of "
            f"zero range ({level}) in all {len(segs)} record(s)."
        )


def shifted(x: np.ndarray, lags: int, start: int) -> np.ndarray:
    """Columns ``x(t - start - k)``, ``k = 0..lags-1`` (zeros before the record), shape (n, lags)."""
    out = np.empty((x.size, lags))
    fill_shifted(out, x, start)
    return out


def fill_shifted(out: np.ndarray, x: np.ndarray, start: int, negate: bool = False) -> None:
    """Write the columns of ``shifted(x, out.shape[1], start)`` (negated if asked) into ``out``.

    ``out`` may be a column block of a larger matrix, so regressors are written in place
    instead of building, negating and stacking separate blocks.
    """
    n, lags = out.shape
    zero = -0.0 if negate else 0.0  # the sign -shifted(...) gives the leading zeros
    for k in range(lags):
        s = min(start + k, n)
        out[:s, k] = zero
        if negate:
            np.negative(x[: n - s], out=out[s:, k])
        else:
            out[s:, k] = x[: n - s]


def regressor(
    blocks: list[list[tuple[np.ndarray, int, int, bool]]], rows: int, out: np.ndarray | None = None
) -> np.ndarray:
    """Stack shifted-signal blocks into one (rows, n_columns) matrix, record by record.

    ``blocks[r]`` lists ``(signal, lags, start, negate)`` for record ``r``; the columns of a
    record are ``[+/-shifted(signal, lags, start), ...]`` side by side and the records are
    stacked below each other (what ``np.vstack`` of ``np.hstack``-ed blocks gives).
    """
    ncol = sum(b[1] for b in blocks[0]) if blocks else 0
    if out is None:
        out = np.empty((rows, ncol))
    r0 = 0
    for rec in blocks:
        n = rec[0][0].size if rec else 0
        c0 = 0
        for sig, lags, start, negate in rec:
            fill_shifted(out[r0 : r0 + n, c0 : c0 + lags], sig, start, negate)
            c0 += lags
        r0 += n
    return out


def lstsq(Phi: np.ndarray, Y: np.ndarray, what: str, strict: bool = True, overwrite: bool = False) -> np.ndarray:
    """Least squares with unit-norm columns; ``overwrite=True`` lets ``Phi`` be scaled in place.

    Raises
    ------
    IdentificationError
        When a column is identically zero, or (``strict``) the regression is rank deficient;
        ``what`` names the regression in the message.
    """
    scale = np.sqrt(np.add.reduce(Phi * Phi, axis=0))  # = np.linalg.norm(Phi, axis=0), same sums
    if np.any(scale == 0):
        raise IdentificationError(
            f"the {what} regression is singular: a regressor column is identically zero (no excitation)."
        )
    if overwrite:
        Phi /= scale
    else:
        Phi = Phi / scale
    theta, _, rank, _ = np.linalg.lstsq(Phi, Y, rcond=None)
    if strict and rank < Phi.shape[1]:
        raise IdentificationError(
            f"the {what} regression is rank deficient ({rank} of {Phi.shape[1]}): the input does not excite this order."
        )
    return theta / scale


def svd_solve(R: np.ndarray, z: np.ndarray, rcond: float) -> tuple[np.ndarray, int]:
    """Minimum-norm solution of ``R theta = z`` (square) with singular values below ``rcond * s_max`` dropped.

    The rank decision of LAPACK's gelsd (``numpy.linalg.lstsq``), here on a small matrix.
    """
    U, s, Vt = np.linalg.svd(R)
    rank = int(np.count_nonzero(s > rcond * s[0])) if s.size and s[0] > 0 else 0
    return Vt[:rank].T @ ((U[:, :rank].T @ z) / s[:rank]), rank


def qr_triangle(W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R, Q^T y)`` of ``W = [Phi | y]`` (Fortran-ordered, overwritten) by one Householder QR (LAPACK dgeqrf)."""
    k = W.shape[1] - 1
    qr, _, _, info = lapack.dgeqrf(W, overwrite_a=1)
    if info != 0:
        raise IdentificationError(f"the QR factorisation failed (LAPACK dgeqrf info {info}).")
    return np.triu(qr[:k, :k]), qr[:k, k].copy()


def triangle_lstsq(R: np.ndarray, z: np.ndarray, m: int, what: str, strict: bool = True) -> np.ndarray:
    """:func:`lstsq` from the QR of the regressor: ``R`` (k x k) and ``Q^T Y`` of an ``m``-row problem.

    The column scaling and the rank decision of :func:`lstsq` (unit-norm columns, gelsd's cut at
    ``eps * max(m, k)``) are applied to ``R``: Householder QR is column-wise backward stable, so
    scaling ``R`` is scaling the regressor.
    """
    k = R.shape[1]
    scale = np.sqrt(np.add.reduce(R * R, axis=0))
    if np.any(scale == 0):
        raise IdentificationError(
            f"the {what} regression is singular: a regressor column is identically zero (no excitation)."
        )
    theta, rank = svd_solve(R / scale, z, np.finfo(float).eps * max(m, k))
    if strict and rank < k:
        raise IdentificationError(
            f"the {what} regression is rank deficient ({rank} of {k}): the input does not excite this order."
        )
    return theta / scale


def lstsq_qr(W: np.ndarray, what: str, strict: bool = True) -> np.ndarray:
    """:func:`lstsq` of ``W[:, :-1] theta = W[:, -1]`` by a Householder QR of ``W`` (overwritten).

    ``W`` is Fortran-ordered with the right-hand side as its last column: the QR of the
    augmented matrix gives ``R`` and ``Q^T Y`` in one pass (:func:`qr_triangle`), then
    :func:`triangle_lstsq`.

    Raises
    ------
    IdentificationError
        As :func:`lstsq`.
    """
    m, k1 = W.shape
    if m < 2 * k1 or not W.flags.f_contiguous:  # short records: the plain route
        return lstsq(np.ascontiguousarray(W[:, :-1]), np.array(W[:, -1]), what, strict)
    R, z = qr_triangle(W)
    return triangle_lstsq(R, z, m, what, strict)


def prefix_lstsq(W: np.ndarray, sizes, what: str, first_only: bool = False) -> dict[int, np.ndarray]:
    """:func:`lstsq` (not strict) of ``W[:, :k] theta = W[:, -1]`` for every ``k`` in ``sizes``, from one QR.

    The leading ``k x k`` block of the triangle of ``W`` and the first ``k`` entries of ``Q^T y``
    are those of the QR of ``W[:, :k]`` alone, so one Householder QR serves every leading column
    block (an order-recursive least squares).  Column scaling and rank decision per block as in
    :func:`triangle_lstsq`.  ``W`` is overwritten; sizes whose block has an identically zero
    column are left out.  ``first_only``: stop at the first size (in the given order) solved.
    """
    m, k1 = W.shape
    out: dict[int, np.ndarray] = {}
    tall = m >= 2 * k1 and W.flags.f_contiguous
    if tall:
        R, z = qr_triangle(W)
    for k in sizes:
        try:
            if tall:
                out[k] = triangle_lstsq(R[:k, :k], z[:k], m, what, strict=False)
            else:  # short records: the plain route, block by block
                out[k] = lstsq(np.ascontiguousarray(W[:, :k]), np.array(W[:, -1]), what, strict=False)
        except IdentificationError:
            continue
        if first_only:
            break
    return out
