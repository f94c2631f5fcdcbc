"""The modified Prandtl-Ishlinskii model of eq. 4: a weighted sum of coupled-play operators.

``y(k) = y0 + sum_i w_i H_i[x - xc; r_i, rc_i, ra_i, rb_i](k)`` over the coupled-play
operators of eq. 3 (:mod:`.operators`); with ``rc = ra = rb = r`` it is the classical PI model
(:mod:`.pi`).  An optional input warp straightens the drive's curvature before the operators.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..._errors import ModelError
from ...display import html_repr, short_repr
from .operators import check_cp_thresholds
from .pi_base import PIBase, operator_vector

__all__ = ["ModifiedPIModel"]


@dataclass(frozen=True, eq=False)
class ModifiedPIModel(PIBase):
    """Modified PI model of eq. 4: weighted sum of coupled-play operators.

    Parameters
    ----------
    r, rc, ra, rb : array_like of shape (n_operators,)
        CP thresholds (see :mod:`stageid.hysteresis.models.operators`), ``0 <= rc <= r``,
        ``0 <= rb <= ra``.
    weights : array_like of shape (n_operators,)
    input_offset, output_offset, state, inputs, outputs, input_limits, creep
        As for :class:`PIModel`.
    input_warp : float, default 0
        ``q`` in (-0.5, 0.5) of an optional monotone quadratic warp of the input before the
        operators (our extension, 0 = the letter's model): ``x = d + q R phi(d / R)``,
        ``d = u - input_offset``, ``phi(t) = t^2`` for ``|t| <= 1``, ``2|t| - 1`` beyond (slope
        ``>= 1 - 2|q| > 0`` everywhere, so the model stays invertible).  It lets the model
        represent the asymmetry a static quadratic adds, which coupled plays alone cannot.
    warp_scale : float, default 1
        ``R``, the half range of the identification input.

    Raises
    ------
    ModelError
        On threshold ordering violations, shape mismatches, non-finite values.

    Examples
    --------
    >>> from stageid.hysteresis import ModifiedPIModel
    >>> m = ModifiedPIModel(r=[0.0, 1.0], rc=[0.0, 0.5], ra=[0.0, 2.0], rb=[0.0, 1.0],
    ...                     weights=[1.0, 1.0])
    >>> m.simulate([0.0, 3.0, 0.0, -3.0])[:, 0].tolist()
    [0.0, 5.0, 1.0, -4.0]
    """

    rc: np.ndarray = field(default=None)  # type: ignore[assignment]
    ra: np.ndarray = field(default=None)  # type: ignore[assignment]
    rb: np.ndarray = field(default=None)  # type: ignore[assignment]
    input_warp: float = 0.0
    warp_scale: float = 1.0
    creep: Any = None

    kind = "modified-pi"

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def to_operator_input(self, u):
        """``x = d + q R phi(d / R)`` with ``d = u - input_offset``, ``q = input_warp``,
        ``R = warp_scale``, ``phi(t) = t^2`` for ``|t| <= 1`` and ``2|t| - 1`` beyond."""
        d = np.asarray(u, dtype=float) - self.input_offset
        q = self.input_warp
        if q == 0.0:
            return d
        R = self.warp_scale
        t = d / R
        a = np.abs(t)
        phi = np.where(a <= 1.0, t * t, 2.0 * a - 1.0)
        return d + q * R * phi

    def from_operator_input(self, x):
        """Inverse of :meth:`to_operator_input` (closed form, piecewise)."""
        x = np.asarray(x, dtype=float)
        q = self.input_warp
        if q == 0.0:
            return x + self.input_offset
        R = self.warp_scale
        tp = x / R
        inner = 2.0 * tp / (1.0 + np.sqrt(np.maximum(1.0 + 4.0 * q * tp, 0.0)))
        t = np.where(
            tp > 1.0 + q, (tp + q) / (1.0 + 2.0 * q), np.where(tp < -1.0 + q, (tp + q) / (1.0 - 2.0 * q), inner)
        )
        return t * R + self.input_offset

    def _warp_slope(self) -> float:
        return 1.0 - 2.0 * abs(self.input_warp)

    def __post_init__(self) -> None:
        r = operator_vector("r", self.r)
        rc = r if self.rc is None else self.rc
        ra = r if self.ra is None else self.ra
        rb = r if self.rb is None else self.rb
        r_, rc_, ra_, rb_ = check_cp_thresholds(r, rc, ra, rb)
        for name, v in (("r", r_), ("rc", rc_), ("ra", ra_), ("rb", rb_)):
            v.setflags(write=False)
            object.__setattr__(self, name, v)
        q, R = float(self.input_warp), float(self.warp_scale)
        if not (np.isfinite(q) and abs(q) < 0.5):
            raise ModelError(f"`input_warp` must be in (-0.5, 0.5) (a monotone warp); got {self.input_warp!r}.")
        if not (np.isfinite(R) and R > 0):
            raise ModelError(f"`warp_scale` must be a positive number; got {self.warp_scale!r}.")
        object.__setattr__(self, "input_warp", q)
        object.__setattr__(self, "warp_scale", R)
        self._init_common()

    def coupled_play_thresholds(self):
        return self.r, self.rc, self.ra, self.rb

    def to_dict(self) -> dict[str, Any]:
        """The ``stageid.hysteresis/1`` dictionary (round-trips byte-stably through ``dumps``)."""
        d = self._base_dict()
        d.update(r=self.r.tolist(), rc=self.rc.tolist(), ra=self.ra.tolist(), rb=self.rb.tolist())
        d.update(input_warp=self.input_warp, warp_scale=self.warp_scale)
        d.update(self._tail_dict())
        return d
