"""Helpers shared by the hysteresis models, their inverse and the compensator.

The lowest module of :mod:`stageid.hysteresis` besides :mod:`.operators`: it imports no other
module of the package, so models (:mod:`.pi`), inversion (:mod:`stageid.hysteresis.inverse`)
and compensation (:mod:`stageid.hysteresis.inverse.compensator`) can all use it without
importing each other.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..._errors import ModelError

__all__ = ["as_input", "check_limits", "packed"]


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


def packed(model: Any) -> np.ndarray:
    """The operator parameters of a (modified) PI model as the inversion kernels take them:
    rows ``r, rc, ra, rb, w``, shape (5, n_operators), C-contiguous."""
    r, rc, ra, rb = model.coupled_play_thresholds()
    return np.ascontiguousarray(np.vstack([r, rc, ra, rb, model.weights]))
