"""Exact inverse of the continuous-cell Preisach model: feedforward drives, streaming and batch.

With a uniform density in each cell (:mod:`.preisach`) the output reached from the current
memory is continuous, piecewise linear and monotone in the input, so each desired output has
an exact root, found per sample by :func:`~stageid.hysteresis.kernels.preisach.preisach_root`
(memory points, then one grid column, then one linear interpolation): ``model(drive) ==
reference`` to rounding wherever the reference is reachable.  Where it is not (beyond the
output of the grid's ends, or beyond the drive limits) the drive is clipped and the memory
follows the clipped drive.  Where the output is flat in the input (zero-weight cells) the
nearest drive is taken.

``PreisachCompensator`` keeps the memory between calls (``step`` per sample, ``run`` per block);
``preisach_feedforward`` is the batch form.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..._errors import ModelError
from ..models.common import as_input, check_limits
from ..models.preisach import PreisachModel

__all__ = ["PreisachCompensator", "preisach_feedforward"]


class PreisachCompensator:
    """Feedforward compensator of a :class:`~stageid.hysteresis.PreisachModel`, with memory.

    Parameters
    ----------
    model : PreisachModel
        Its ``state`` is the starting memory; its weights must be non-negative (a monotone
        model).
    limits : (float, float), optional
        Drive limits, ``low < high``; default ``model.input_limits``.  The drive is clipped to
        them; beyond the grid the model is flat, so drives never leave ``model.input_range``.

    Raises
    ------
    ModelError
        For a model with negative weights or malformed limits; :meth:`step` and :meth:`run` for
        a non-finite desired output (the memory is then unchanged).

    Examples
    --------
    >>> import numpy as np
    >>> m = PreisachModel((0.0, 2.0), [0.5, 1.0, 0.5])
    >>> comp = PreisachCompensator(m)
    >>> u = comp.run([0.5, 1.5, 1.0])[:, 0]
    >>> np.round(m(u), 12).tolist()
    [0.5, 1.5, 1.0]
    """

    def __init__(self, model: PreisachModel, limits: tuple[float, float] | None = None) -> None:
        if not isinstance(model, PreisachModel):
            raise ModelError(f"PreisachCompensator needs a PreisachModel; got {type(model).__name__}.")
        if np.any(model.weights < 0):
            raise ModelError("a Preisach model with negative weights is not monotone: no inverse.")
        self.model = model
        lim = check_limits(limits if limits is not None else model.input_limits)
        self.limits = lim
        self._lo, self._hi = (-np.inf, np.inf) if lim is None else lim
        self.reset()

    def reset(self, state: Any = None) -> None:
        """Restart from the memory ``state`` (default the model's own)."""
        model = self.model if state is None else self.model.with_state(state)
        self._P, self._cum, self._top, self._cur = model.memory_arrays(64)

    @property
    def state(self) -> np.ndarray:
        """The model's memory after the last drive sample (a ``state`` for ``with_state``)."""
        return np.r_[self._P[1 : self._top + 1], self._cur]

    def step(self, y_ref: float) -> float:
        """Drive for one desired output sample (the memory advances by one sample)."""
        return float(self.run(np.array([float(y_ref)]))[0, 0])

    def run(self, y_ref: object) -> np.ndarray:
        """Drives for a block of desired outputs, shape (n_samples, 1); continues the memory."""
        from ..kernels.preisach import preisach_invert

        target = np.ascontiguousarray(as_input(y_ref, "y_ref") - self.model.output_offset)
        need = self._top + target.size + 3
        if need > self._P.size:  # room for one reversal point per sample
            self._P = np.r_[self._P, np.empty(need)]
            self._cum = np.r_[self._cum, np.empty(need)]
        En, wd = self.model.everett_table
        lo, h = self.model.input_range[0], self.model.step
        u, self._top, self._cur = preisach_invert(
            target, En, wd, lo, h, self._P, self._cum, self._top, self._cur, self._lo, self._hi
        )
        return u[:, None]


def preisach_feedforward(model: PreisachModel, y_ref: object, limits: tuple[float, float] | None = None) -> np.ndarray:
    """Batch feedforward: the drive, shape (n_samples, 1), from the model's memory.

    ``model.simulate(drive)`` equals ``y_ref`` to rounding where ``y_ref`` is reachable
    within the limits (default ``model.input_limits``).
    """
    return PreisachCompensator(model, limits).run(y_ref)
