"""Inverse-model feedforward compensation (Fig. 9 of the letter), streaming and batch.

``Compensator(model)`` turns a desired output ``y_ref(k)`` into the drive ``u(k)`` that the
model says produces it, so the cascade compensator -> actuator is close to the identity.

* classical :class:`~stageid.hysteresis.PIModel`: the closed-form inverse PI model
  (:func:`~stageid.hysteresis.pi_inverse`), one play-operator update per threshold and sample;
* :class:`~stageid.hysteresis.ModifiedPIModel`: the per-sample monotone inversion of
  :func:`~stageid.hysteresis.invert` (the exact root of each sample's equation, to rounding:
  :func:`~stageid.hysteresis.models.common.residual_bound`);
* either with a ``creep`` term: per-sample inversion with the creep state
  (:class:`CreepInverse`, here because it drives rate-independent compensators and the
  compensator delegates to it; the creep term itself is :mod:`~stageid.hysteresis.models.creep`).

The compensator is the one mutable object of the package: it holds the operator state between
calls, as a real-time loop needs (``step`` per sample; ``run`` for a block, continuing the
state).  Drive limits are respected: the drive is clipped to ``limits`` and the state follows
the clipped drive, so the compensator stays consistent with the actuator it drives.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..._errors import ModelError
from ..models.common import as_input, check_limits, limited_drive, packed, residual_bound
from ..models.operators import OperatorState
from ..models.pi import ModifiedPIModel, PIModel
from .closed_form import forward_state, inverse_state, pi_inverse

__all__ = ["Compensator", "compensate", "CreepInverse", "residual_bound"]

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
        from .. import kernels  # numba: imported on first use

        self._k = kernels
        self.model = model
        self._creep = None
        if getattr(model, "creep", None) is not None:  # rate dependent: delegate (CreepInverse below)
            self._creep = CreepInverse(model, limits, dt)
            self.limits = self._creep.limits
            return
        lim = check_limits(limits if limits is not None else model.input_limits)
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
            self._P = packed(model)
            self._smin = smin
            self._err_w, self._err_r = residual_bound(model)
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
            x = self._k.cp_invert_step(
                self._P, self._z, self._x, target, self._lo, self._hi, self._smin, self._err_w, self._err_r
            )
            self._x = x
            if self.model.input_warp != 0.0:
                return float(self._unwarped_drive(np.array([x]))[0])
        return x + self.model.input_offset

    def run(self, y_ref: object) -> np.ndarray:
        """Drives for a block of desired outputs, shape (n_samples, 1); continues the state."""
        if self._creep is not None:
            return self._creep.run(y_ref)
        target = np.ascontiguousarray(as_input(y_ref, self.model.outputs[0]) - self.model.output_offset)
        if self._inverse is not None and not np.isfinite(self._lo) and not np.isfinite(self._hi):
            x, z = self._k.play_stream(target, self._P, self._z, self._lo, self._hi)
            self._z = z
            if x.size:
                self._x = float(x[-1])
        elif self._inverse is not None:
            x = np.array([self.step(v + self.model.output_offset) for v in target]) - self.model.input_offset
        else:
            x, z, xf = self._k.cp_invert(
                target, self._P, self._z, self._x, self._lo, self._hi, self._smin, self._err_w, self._err_r
            )
            self._z = z
            self._x = float(xf)
            if self.model.input_warp != 0.0:
                return self._unwarped_drive(x)[:, None]
        return (x + self.model.input_offset)[:, None]

    def _unwarped_drive(self, x: np.ndarray) -> np.ndarray:
        return limited_drive(self.model, x, self.limits, (self._lo, self._hi))

    @property
    def solves_per_sample(self) -> bool:
        """True for a modified-PI model without creep: each drive is a per-sample root solve
        (a classical PI uses its closed-form inverse model, a creep model delegates)."""
        return self._creep is None and self._inverse is None

    def run_under_creep(
        self, yr: np.ndarray, creep: tuple[np.ndarray, np.ndarray, np.ndarray], u_prev: float, g: float, tol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The compiled loop of :class:`CreepInverse` with this (per-sample) compensator inside.

        ``creep`` is the creep lags' ``(a, ca, state)``; ``u_prev`` the last drive, ``g`` the
        gain and ``tol`` the tolerance of the fixed point on the creep excess.  Continues and
        updates this compensator's operator state; returns the drives and the lags' new state.
        Only for :attr:`solves_per_sample` compensators.
        """
        a, ca, s = creep
        u, z, x, s = self._k.cp_invert_creep(
            yr,
            self._P,
            self._z,
            self._x,
            self._lo,
            self._hi,
            self._smin,
            self._err_w,
            self._err_r,
            float(self.model.output_offset),
            float(self.model.input_offset),
            a,
            ca,
            s,
            float(u_prev),
            float(g),
            float(tol),
        )
        self._z, self._x = z, float(x)
        return u, s


def compensate(
    model: PIModel | ModifiedPIModel, y_ref: object, limits: tuple[float, float] | None = None
) -> np.ndarray:
    """Batch feedforward: the drive of shape (n_samples, 1) for a desired output record
    ``y_ref`` (array_like of shape (n_samples,) or (n_samples, 1), finite), from the model's own
    state: ``Compensator(model, limits).run(y_ref)``, with the limits and errors of
    :class:`Compensator`.

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


class CreepInverse:
    """Per-sample inverse of a PI / modified-PI model with a :class:`CreepTerm` (see module notes).

    Used by :class:`~stageid.hysteresis.Compensator` and :func:`~stageid.hysteresis.invert`
    when ``model.creep`` is set; not usually built directly.

    Parameters
    ----------
    model : PIModel or ModifiedPIModel
        With ``model.creep`` set.
    limits : (float, float), optional
        Drive limits (default ``model.input_limits``).
    dt : float, optional
        Sampling period [s] of the reference (default the creep term's ``sample_time``).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.inverse.compensator import CreepInverse
    >>> from stageid.hysteresis.models.creep import CreepTerm
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5], creep=CreepTerm([0.5], [0.2], 0.01))
    >>> yd = np.array([0.0, 1.0, 2.0, 1.5])
    >>> u = CreepInverse(m).run(yd)
    >>> bool(np.allclose(m.simulate(u)[:, 0], yd))
    True
    """

    def __init__(self, model: Any, limits: tuple[float, float] | None = None, dt: float | None = None) -> None:
        creep = getattr(model, "creep", None)
        if creep is None:
            raise ModelError("CreepInverse needs a model with a creep term; got model.creep = None.")
        self.model = model
        self.creep = creep
        self._a = creep.poles(dt)
        self._ca = creep.weights * self._a
        self._g = creep.instantaneous_gain(dt)
        self._G = float(np.sum(creep.weights))
        base = replace(model, creep=None)
        # fold the instantaneous creep gain into the linear operator (r = 0: the identity); the
        # first sample of a creep at rest at that sample's input has the whole static gain G
        self._folded = bool(base.r[0] == 0.0)

        def folded(gain: float):
            if not self._folded:
                return Compensator(base, limits)
            w = np.array(base.weights)
            w[0] += gain
            return Compensator(replace(base, weights=w), limits)

        self._inner = folded(self._g)
        self._first = folded(self._G)
        self.limits = self._inner.limits
        scale = float(np.sum(np.abs(model.weights)) * (1.0 + np.max(model.r)) + np.sum(creep.weights))
        self._tol = 1e-12 * max(scale, 1e-300)
        self.reset()

    def reset(self, state: OperatorState | None = None, creep_state: object | None = None) -> None:
        """Restart from an operator ``state`` (default the model's) and lag outputs ``creep_state``
        (default the creep term's; ``None`` there: at rest at the first drive, as
        :meth:`~stageid.hysteresis.PIModel.simulate` assumes)."""
        self._inner.reset(state)
        st = self.creep.state if creep_state is None else np.asarray(creep_state, dtype=float).reshape(-1)
        x = (self.model.state if state is None else state).x
        self._u_prev = float(self.model.from_operator_input(x))
        self._fresh = st is None
        if st is None:
            st = np.full(self.creep.n_lags, self._u_prev)
        if st.size != self.creep.n_lags:
            raise ModelError(f"creep state must hold {self.creep.n_lags} lag outputs; got {st.size}.")
        self._s = np.array(st, dtype=float)

    @property
    def state(self) -> OperatorState:
        """Operator state after the last sample."""
        return self._inner.state

    @property
    def creep_state(self) -> np.ndarray:
        """Lag outputs after the last sample, shape (n_lags,)."""
        return self._s.copy()

    def _excess(self, u: float) -> float:
        # the part of g*u the folded inner model does not produce: g*(u - x(u)), or g*u unfolded
        return u - float(self.model.to_operator_input(u)) if self._folded else u

    def step(self, y_ref: float) -> float:
        """Drive for one desired output sample; advances the operator and creep states.

        Raises :class:`ModelError` (state unchanged) if ``y_ref`` is not finite.
        """
        y_ref = float(y_ref)
        if not math.isfinite(y_ref):
            raise ModelError(
                f"desired output `y_ref` must be finite; got {y_ref} (the compensator state is unchanged)."
            )
        if not self._fresh and self._compiled:
            return float(self._run_compiled(np.array([y_ref]))[0])
        if self._fresh:  # creep at rest at this sample's (unknown) input: output G*u, no memory
            inner, g, h = self._first, self._G, 0.0
            inner.reset(self._inner.state)
        else:
            inner, g, h = self._inner, self._g, float(self._ca @ self._s)
        saved = inner.state
        e = self._excess(self._u_prev)
        u = float("nan")
        for _ in range(100):
            u = float(inner.step(float(y_ref) - h - g * e))
            e_new = self._excess(u)
            if abs(g * (e_new - e)) <= self._tol:
                break
            inner.reset(saved)
            e = e_new
        if self._fresh:
            self._inner.reset(inner.state)
            self._s = np.full(self.creep.n_lags, u)
            self._fresh = False
        else:
            self._s = self._a * self._s + (1.0 - self._a) * u
        self._u_prev = u
        return u

    def run(self, y_ref: object) -> np.ndarray:
        """Drives for a block of desired outputs, shape (n_samples, 1); continues the state.

        A modified-PI model without input warp runs in one compiled loop (the same arithmetic
        as :meth:`step`); other models step sample by sample from Python.
        """
        yr = np.ascontiguousarray(as_input(y_ref, self.model.outputs[0]), dtype=float)
        out = np.empty(yr.size)
        k = 0
        if self._fresh and yr.size:
            out[0] = self.step(yr[0])
            k = 1
        if self._compiled:
            out[k:] = self._run_compiled(yr[k:])
        else:
            for i in range(k, yr.size):
                out[i] = self.step(yr[i])
        return out.reshape(-1, 1)

    @property
    def _compiled(self) -> bool:
        return self._folded and self._inner.solves_per_sample and getattr(self.model, "input_warp", 0.0) == 0.0

    def _run_compiled(self, yr: np.ndarray) -> np.ndarray:
        """:meth:`step` for every sample of ``yr`` in one compiled loop (state not fresh)."""
        if not yr.size:
            return yr.copy()
        u, self._s = self._inner.run_under_creep(yr, (self._a, self._ca, self._s), self._u_prev, self._g, self._tol)
        self._u_prev = float(u[-1])
        return u
