"""Inverse-model feedforward compensation (Fig. 9 of the letter), streaming and batch.

``Compensator(model)`` turns a desired output ``y_ref(k)`` into the drive ``u(k)`` that the
model says produces it, so the cascade compensator -> actuator is close to the identity.

* classical :class:`~stageid.hysteresis.PIModel`: the closed-form inverse PI model
  (:func:`~stageid.hysteresis.pi_inverse`), one play-operator update per threshold and sample;
* :class:`~stageid.hysteresis.ModifiedPIModel`: the per-sample monotone inversion of
  :func:`~stageid.hysteresis.invert`;
* either with a ``creep`` term: per-sample inversion with the creep state
  (:class:`~stageid.hysteresis.creep.CreepInverse`).

The compensator is the one mutable object of the package: it holds the operator state between
calls, as a real-time loop needs (``step`` per sample; ``run`` for a block, continuing the
state).  Drive limits are respected: the drive is clipped to ``limits`` and the state follows
the clipped drive, so the compensator stays consistent with the actuator it drives.
"""

from __future__ import annotations

import math

import numpy as np

from .._errors import ModelError
from .inverse import _packed, _tolerance, forward_state, inverse_state, pi_inverse
from .operators import OperatorState
from .pi import ModifiedPIModel, PIModel, _as_input

__all__ = ["Compensator", "compensate"]

_isfinite = math.isfinite


class Compensator:
    """Feedforward hysteresis compensator with state.

    Parameters
    ----------
    model : PIModel or ModifiedPIModel
        The identified actuator model (its state is the starting state).
    limits : (float, float), optional
        Drive limits in input units, ``low < high``; default ``model.input_limits`` (for a
        model from :class:`~stageid.hysteresis.PIIdentifier` the identified input range).
        The drive is clipped to them, silently (the ``stageid compensate`` command warns).
        The drive is unlimited only when both ``limits`` and ``model.input_limits`` are None;
        pass ``(-numpy.inf, numpy.inf)`` to lift a model's own limits.
    dt : float, optional
        Sampling period [s] of the reference; used only by a model's ``creep`` term (default
        its ``sample_time``).

    Raises
    ------
    ModelError
        If the model is not invertible or ``limits`` are malformed; :meth:`step` and
        :meth:`run` raise it for a non-finite desired output (the state is then unchanged).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, Compensator
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> comp = Compensator(m)
    >>> u = [comp.step(v) for v in (0.0, 2.5, 1.5)]
    >>> np.round(u, 12).tolist()
    [0.0, 2.0, 1.0]
    """

    def __init__(
        self, model: PIModel | ModifiedPIModel, limits: tuple[float, float] | None = None, dt: float | None = None
    ) -> None:
        from . import kernels

        self._k = kernels
        self.model = model
        self._creep = None
        if getattr(model, "creep", None) is not None:  # rate dependent: delegate (see creep.py)
            from .creep import CreepInverse

            self._creep = CreepInverse(model, limits, dt)
            self.limits = self._creep.limits
            return
        lim = _check_limits(limits if limits is not None else model.input_limits)
        self.limits = lim
        self._lo = -np.inf if lim is None else float(model.to_operator_input(self.limits[0]))
        self._hi = np.inf if lim is None else float(model.to_operator_input(self.limits[1]))
        if isinstance(model, PIModel):
            self._inverse = pi_inverse(model)
            self._P = np.ascontiguousarray(np.vstack([self._inverse.r, self._inverse.weights]))
        else:
            smin = model.min_slope()
            if not smin > 0:
                raise ModelError(f"model is not invertible: minimum slope {smin:g}; expected > 0.")
            self._inverse = None
            self._P = _packed(model)
            self._smin = smin
            self._tol = _tolerance(model)
        self.reset()

    def reset(self, state: OperatorState | None = None) -> None:
        """Restart from ``state`` (forward-model state; default the model's own state)."""
        if self._creep is not None:
            self._creep.reset(state)
            return
        st = self.model.state if state is None else state
        if st.z.size != self.model.n_operators:
            raise ModelError(f"state must hold {self.model.n_operators} operator outputs; got {st.z.size}.")
        if self._inverse is not None:
            inv = inverse_state(self.model, st)
            self._z = np.array(inv.z)
            self._x = float(st.x)
        else:
            self._z = np.array(st.z)
            self._x = float(st.x)

    @property
    def state(self) -> OperatorState:
        """The forward model's operator state after the last sample."""
        if self._creep is not None:
            return self._creep.state
        if self._inverse is not None:
            return forward_state(self._inverse, OperatorState(self._z[0], self._z))
        return OperatorState(self._x, self._z)

    def step(self, y_ref: float) -> float:
        """Drive for one desired output sample (state advances by one sample).

        Raises
        ------
        ModelError
            If ``y_ref`` is not a finite number; the state is then unchanged.
        """
        y = float(y_ref)
        if not _isfinite(y):  # one float check keeps a NaN/inf out of the operator state
            raise ModelError(f"desired output `y_ref` must be finite; got {y} (the compensator state is unchanged).")
        if self._creep is not None:
            return self._creep.step(y)
        target = y - self.model.output_offset
        if self._inverse is not None:
            saved = self._z.copy()
            x = self._k.play_step(self._P, self._z, target)
            if x < self._lo or x > self._hi:
                x = min(max(x, self._lo), self._hi)
                fwd = forward_state(self._inverse, OperatorState(saved[0], saved))
                _, zf = self._k.play_bank(np.array([x]), self.model.r, np.array(fwd.z))
                self._z = np.array(inverse_state(self.model, OperatorState(x, zf)).z)
            self._x = x
        else:
            x = self._k.cp_invert_step(self._P, self._z, self._x, target, self._lo, self._hi, self._smin, self._tol)
            self._x = x
            if self.model.input_warp != 0.0:
                return self._clip(float(self.model.from_operator_input(x)))
        return x + self.model.input_offset

    def run(self, y_ref: object) -> np.ndarray:
        """Drives for a block of desired outputs, shape (n_samples, 1); continues the state."""
        if self._creep is not None:
            return self._creep.run(y_ref)
        target = np.ascontiguousarray(_as_input(y_ref, self.model.outputs[0]) - self.model.output_offset)
        if self._inverse is not None and not np.isfinite(self._lo) and not np.isfinite(self._hi):
            x, z = self._k.play_stream(target, self._P, self._z, self._lo, self._hi)
            self._z = z
            if x.size:
                self._x = float(x[-1])
        elif self._inverse is not None:
            x = np.array([self.step(v + self.model.output_offset) for v in target]) - self.model.input_offset
        else:
            x, z, xf = self._k.cp_invert(target, self._P, self._z, self._x, self._lo, self._hi, self._smin, self._tol)
            self._z = z
            self._x = float(xf)
            if self.model.input_warp != 0.0:
                u = self.model.from_operator_input(x)
                return (u if self.limits is None else np.clip(u, *self.limits))[:, None]
        return (x + self.model.input_offset)[:, None]

    def _clip(self, u: float) -> float:
        return u if self.limits is None else min(max(u, self.limits[0]), self.limits[1])


def _check_limits(lim: object) -> tuple[float, float] | None:
    """``(low, high)`` as floats, or None; a one-line ModelError unless two numbers with low < high."""
    if lim is None:
        return None
    try:
        lo, hi = (float(v) for v in lim)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise ModelError(f"`limits` must be (low, high), two numbers with low < high; got {lim!r:.60}.") from None
    if not lo < hi:  # also refuses NaN
        raise ModelError(f"`limits` must be (low, high) with low < high; got {lim!r:.60}.")
    return lo, hi


def compensate(
    model: PIModel | ModifiedPIModel, y_ref: object, limits: tuple[float, float] | None = None
) -> np.ndarray:
    """Batch feedforward: the drive of shape (n_samples, 1) for a desired output record.

    Parameters
    ----------
    model : PIModel or ModifiedPIModel
    y_ref : array_like of shape (n_samples, 1) or (n_samples,)
        Desired outputs (finite).
    limits : (float, float), optional
        Drive limits ``(low, high)``, ``low < high``; default ``model.input_limits`` (an
        identified model's identified input range).  The drive is clipped to them; it is
        unlimited only when both are None (``(-numpy.inf, numpy.inf)`` lifts a model's limits).

    Returns
    -------
    ndarray of shape (n_samples, 1)

    Raises
    ------
    ModelError
        Non-invertible model, malformed ``limits`` or a non-finite ``y_ref``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, compensate
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> yref = np.array([0.0, 2.5, 1.5])
    >>> bool(np.allclose(m.simulate(compensate(m, yref))[:, 0], yref))
    True
    """
    return Compensator(model, limits).run(y_ref)
