"""Helpers shared by the hysteresis models, their inverse and the compensator.

The lowest module of :mod:`stageid.hysteresis`: it imports no other module of the package,
so the operators (:mod:`.operators`), models (:mod:`.pi`), inversion (:mod:`stageid.hysteresis.inverse`)
and compensation (:mod:`stageid.hysteresis.inverse.compensator`) can all use it without
importing each other.  Besides the checks: a model's operator parameters as the inversion
kernels take them (:func:`packed`) and the rounding bound of its computed output at which
the per-sample inversion stops (:func:`residual_bound`), and the drive an inversion gives for
operator inputs within drive limits (:func:`limited_drive`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..._errors import ModelError

__all__ = ["as_input", "check_limits", "limited_drive", "packed", "residual_bound"]


def as_input(u: object, name: str) -> np.ndarray:
    """A finite input record as a float array of shape (n_samples,); ModelError naming ``name``.

    Accepts shape (n_samples,) or (n_samples, 1): hysteresis models have one input.
    """
    arr = np.asarray(u, dtype=float)
    if arr.ndim == 2 and arr.shape[1] == 1:
        arr = arr[:, 0]
    if arr.ndim != 1:
        raise ModelError(f"input `{name}` must have shape (n_samples, 1) or (n_samples,); got {np.shape(u)}.")
    if not np.all(np.isfinite(arr)):
        i = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise ModelError(f"input `{name}` must be finite; got {arr[i]} at row {i}.")
    return arr


def check_limits(lim: object) -> tuple[float, float] | None:
    """Drive limits ``(low, high)`` as floats, or None; a one-line ModelError unless two numbers
    with low < high (infinite ends allowed: they lift a model's own limits)."""
    if lim is None:
        return None
    try:
        lo, hi = (float(v) for v in lim)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ModelError(f"`limits` must be (low, high), two numbers with low < high; got {lim!r:.60}.") from None
    if not lo < hi:  # also refuses NaN
        raise ModelError(f"`limits` must be (low, high) with low < high; got {lim!r:.60}.")
    return lo, hi


def limited_drive(
    model: Any,
    x: np.ndarray,
    limits: tuple[float, float] | None,
    operator_limits: tuple[float, float],
) -> np.ndarray:
    """Drives for the operator inputs ``x`` (clipped to ``operator_limits``, the drive
    ``limits`` on the operator side), within ``limits``.  With an input warp, an input clipped
    at an operator-side limit is the drive limit itself: the warp's round trip would leave it a
    rounding error inside, where it reads as a drive that hit no limit."""
    u = model.from_operator_input(x)
    if limits is None:
        return u
    u = np.clip(u, float(limits[0]), float(limits[1]))
    if getattr(model, "input_warp", 0.0) == 0.0:  # the classical model has no warp
        return u
    lo, hi = operator_limits
    return np.where(x >= hi, float(limits[1]), np.where(x <= lo, float(limits[0]), u))


def packed(model: Any) -> np.ndarray:
    """The operator parameters of a (modified) PI model as the inversion kernels take them:
    rows ``r, rc, ra, rb, w``, shape (5, n_operators), C-contiguous."""
    r, rc, ra, rb = model.coupled_play_thresholds()
    return np.ascontiguousarray(np.vstack([r, rc, ra, rb, model.weights]))


def residual_bound(model: Any) -> tuple[float, float]:
    """The rounding error of the computed per-sample output ``F(x) = sum_i w_i CP_i(x; z_i)``.

    ``|computed F(x) - F(x)| <= err_w (|x| + err_r)`` with ``err_w = 4 (m + 2) u sum|w_i|`` and
    ``err_r`` the largest threshold (``u = 2**-53``, ``m`` operators): each operator output is one
    rounded ``x -+ threshold`` (at most ``|x| + err_r`` in size), each term one rounded product,
    the sum ``m - 1`` rounded additions; the factor 4 also covers the rounding of the Newton step
    that lands on the root.  The per-sample inversion stops once ``|F(x) - target|`` is within
    this bound: ``x`` is then the exact root to rounding.

    Returns
    -------
    (err_w, err_r) : (float, float)

    Examples
    --------
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.models.common import residual_bound
    >>> err_w, err_r = residual_bound(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]))
    >>> err_r, bool(err_w < 1e-14)
    (1.0, True)
    """
    thresholds = np.abs(np.vstack(model.coupled_play_thresholds()))
    err_w = 4.0 * (model.n_operators + 2) * 2.0**-53 * float(np.sum(np.abs(model.weights)))
    return err_w, float(np.max(thresholds))
