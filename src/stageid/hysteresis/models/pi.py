"""Classical and modified Prandtl-Ishlinskii (PI) hysteresis models.

Classical PI model
    ``y(k) = y0 + sum_i w_i H_{r_i}[x - xc](k)``, a weighted sum of play operators (eq. 1)
    acting on the input ``x`` measured from the centre ``xc``.  The operator with threshold
    ``r = 0`` is the identity, so its weight is the linear term ``p0 x`` of the PI model.

Modified PI model (eq. 4)
    ``y(k) = y0 + sum_i w_i H_i[x - xc; r_i, rc_i, ra_i, rb_i](k)``, the same sum over
    coupled-play operators (eq. 3, read as in :mod:`stageid.hysteresis.models.operators`).  With
    ``rc = ra = rb = r`` it is the classical PI model.

The modified model lives in :mod:`.modified_pi` (re-exported here), what both share in
:mod:`.pi_base`.  Both models are immutable and carry their operator state (last input, operator outputs),
so :meth:`run` returns the final state and :meth:`with_state` resumes from it.  The state's
``x`` is in operator coordinates (input minus ``input_offset``, warped for a modified PI model
with ``input_warp``: :meth:`to_operator_input`).

Optional creep (our extension, :mod:`stageid.hysteresis.models.creep`): ``creep=CreepTerm(...)``
adds ``sum_j c_j lowpass_{tau_j}(u)`` (first-order lags of the input, ``c_j >= 0``) to the
output; the model is then rate dependent and ``simulate(u, dt)`` uses ``dt``.  Without it
(the default) nothing changes.

Monotonicity (invertibility): the model output is a nondecreasing function of the current
input for every state when ``w_0 + sum_{i>=1} min(w_i, 0) > 0`` (the slope of the output with
respect to the input is ``sum`` of the weights of the operators on a moving branch, which is
never below that bound).  For the classical model the exact condition is weaker: every
initial-loading slope ``sum_{i<=j} w_i`` (thresholds ascending) must be positive.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._errors import ModelError
from ...display import html_repr, short_repr
from .modified_pi import ModifiedPIModel
from .pi_base import HYSTERESIS_FORMAT, STATE_KINDS, PIBase

__all__ = ["PIModel", "ModifiedPIModel", "HYSTERESIS_FORMAT", "STATE_KINDS"]


@dataclass(frozen=True, eq=False)
class PIModel(PIBase):
    """Classical Prandtl-Ishlinskii model: weighted sum of play operators plus a linear term.

    Parameters
    ----------
    r : array_like of shape (n_operators,)
        Thresholds, >= 0, ascending; ``r[0] = 0`` makes ``weights[0]`` the linear gain.
    weights : array_like of shape (n_operators,)
        Operator weights.
    input_offset : float, default 0
        Input centre ``xc``: the operators see ``x - xc``.
    output_offset : float, default 0
        Output offset ``y0`` added to the weighted sum (sensor zero).
    state : OperatorState, optional
        Operator state to start from; default ``x0 = z0 = 0`` (eq. 2).
    inputs, outputs : tuple of one str
        Channel names, default ``("V",)`` and ``("y",)``.
    input_limits : (float, float), optional
        Drive range, used as the default limits of the compensator (which clips to it);
        :class:`~stageid.hysteresis.PIIdentifier` stores the identified input range here.
    creep : CreepTerm, optional
        Linear creep added to the output (:mod:`stageid.hysteresis.models.creep`); default none
        (rate independent).

    Raises
    ------
    ModelError
        On negative or unsorted thresholds, shape mismatches, non-finite values.

    Examples
    --------
    >>> from stageid.hysteresis import PIModel
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> y, state = m.run([0.0, 2.0, 1.0])
    >>> y[:, 0].tolist(), state.z.tolist()
    ([0.0, 2.5, 1.5], [1.0, 1.0])
    """

    creep: Any = None

    kind = "pi"

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def __post_init__(self) -> None:
        self._init_common()
        if np.any(np.diff(self.r) <= 0):
            raise ModelError(f"thresholds `r` of a PI model must be strictly ascending; got {self.r.tolist()}.")

    def coupled_play_thresholds(self):
        return self.r, self.r, self.r, self.r

    def initial_loading_slopes(self) -> np.ndarray:
        """Slopes ``sum_{i<=j} w_i`` of the initial loading curve on ``[r_j, r_{j+1}]``, shape (n_operators,)."""
        return np.cumsum(self.weights)

    def to_modified(self) -> ModifiedPIModel:
        """The same model written as a modified PI model (``rc = ra = rb = r``)."""
        return ModifiedPIModel(
            r=self.r,
            rc=self.r,
            ra=self.r,
            rb=self.r,
            weights=self.weights,
            input_offset=self.input_offset,
            output_offset=self.output_offset,
            state=self.state,
            inputs=self.inputs,
            outputs=self.outputs,
            input_limits=self.input_limits,
            creep=self.creep,
        )

    def to_dict(self) -> dict[str, Any]:
        """The ``stageid.hysteresis/1`` dictionary (round-trips byte-stably through ``dumps``)."""
        d = self._base_dict()
        d["r"] = self.r.tolist()
        d.update(self._tail_dict())
        return d
