"""Linear creep term of a PI model: a weighted sum of first-order lags of the input.

Piezo creep is the slow part of the response to an input step (displacement keeps growing for
seconds after the voltage settled).  The standard linear description adds to the
rate-independent hysteresis model a bank of first-order lags of the drive ``u`` (e.g. Croft,
Shed & Devasia 2001; Kuhnen's creep operator in discrete form)::

    s_j(k) = a_j s_j(k-1) + (1 - a_j) u(k),    a_j = exp(-dt / tau_j)
    y_c(k) = sum_j c_j s_j(k)

with time constants ``tau_j`` (seconds, a few log-spaced values) and weights ``c_j >= 0``.
At rest (``u`` constant) every ``s_j = u``, so ``y_c = (sum c_j) u``: the creep adds static
gain that builds up with the time constants.

Why ``c_j >= 0``: the output of the current sample depends on the current input through
``g = sum_j c_j (1 - a_j) >= 0`` (the rest is memory), so the model stays a nondecreasing
function of the current input and the per-sample inverse of :mod:`stageid.hysteresis.inverse` still has exactly
one solution.

State: the lag outputs ``s`` (input units).  ``state=None`` means *at rest at the first input
sample* of every simulation (records start after an idle stretch): the policy under which
:class:`~stageid.hysteresis.PIIdentifier` fits the creep and the one
:func:`~stageid.hysteresis.align_record` applies to other records.  The compensator follows it:
its first drive is solved with the creep at rest at that drive (output ``(sum_j c_j) u``).

Inversion with creep (:class:`stageid.hysteresis.inverse.compensator.CreepInverse`): per sample after the first, the memory part
``h = sum_j c_j a_j s_j(k-1)`` is known, and the instantaneous gain ``g`` is folded into the
linear operator's weight (``r_0 = 0``) of the rate-independent model, which is then inverted
by the existing :class:`~stageid.hysteresis.Compensator`.  Without an input warp this is
exact in one pass; with the warp of :class:`~stageid.hysteresis.ModifiedPIModel` the small
remainder ``g (u - x)`` is resolved by fixed-point iteration (a contraction with factor below
``2 |q| g / min_slope``, ~1e-3 in practice).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..._errors import ModelError, ModelFormatError
from ...checks import is_real, shown

__all__ = ["CreepTerm"]


def _positive(name: str, value: object) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ModelError(f"`{name}` must be a positive number of seconds; got {value!r}.") from None
    if not (np.isfinite(v) and v > 0):
        raise ModelError(f"`{name}` must be a positive number of seconds; got {value!r}.")
    return v


@dataclass(frozen=True, eq=False)
class CreepTerm:
    """Linear creep: ``y_c = sum_j c_j lowpass_{tau_j}(u)`` (first-order lags, see module notes).

    Parameters
    ----------
    time_constants : array_like of shape (n_lags,)
        ``tau_j`` in seconds, > 0.
    weights : array_like of shape (n_lags,)
        ``c_j`` (output units per input unit), >= 0.
    sample_time : float
        Sampling period ``dt`` [s] of the records the term was identified on (used when a
        simulation does not pass its own ``dt``).
    state : array_like of shape (n_lags,), optional
        Lag outputs ``s_j`` before the first sample (input units); ``None`` = at rest at the
        first input sample.

    Raises
    ------
    ModelError
        Non-positive time constants or sample time, negative or non-finite weights, shape
        mismatches.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis.models.creep import CreepTerm
    >>> c = CreepTerm(time_constants=[1.0], weights=[0.5], sample_time=0.1)
    >>> y, s = c.run(np.r_[0.0, np.ones(3)])
    >>> np.round(y, 4).tolist()
    [0.0, 0.0476, 0.0906, 0.1296]
    """

    time_constants: np.ndarray
    weights: np.ndarray
    sample_time: float
    state: np.ndarray | None = None

    def __post_init__(self) -> None:
        tau = np.array(self.time_constants, dtype=float, copy=True).reshape(-1)
        if tau.size == 0 or not np.all(np.isfinite(tau)) or np.any(tau <= 0):
            raise ModelError(f"creep `time_constants` must be positive seconds (at least one); got {tau.tolist()}.")
        c = np.array(self.weights, dtype=float, copy=True).reshape(-1)
        if c.size != tau.size:
            raise ModelError(f"creep `weights` must have {tau.size} entries (one per time constant); got {c.size}.")
        if not np.all(np.isfinite(c)) or np.any(c < 0):
            raise ModelError(f"creep `weights` must be finite and >= 0 (monotone model); got {c.tolist()}.")
        dt = _positive("sample_time", self.sample_time)
        st = None
        if self.state is not None:
            st = np.array(self.state, dtype=float, copy=True).reshape(-1)
            if st.size != tau.size or not np.all(np.isfinite(st)):
                raise ModelError(f"creep `state` must hold {tau.size} finite lag outputs; got {st.tolist()}.")
            st.setflags(write=False)
        tau.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "time_constants", tau)
        object.__setattr__(self, "weights", c)
        object.__setattr__(self, "sample_time", dt)
        object.__setattr__(self, "state", st)

    @property
    def n_lags(self) -> int:
        """Number of first-order lags."""
        return int(self.time_constants.size)

    def poles(self, dt: float | None = None) -> np.ndarray:
        """``a_j = exp(-dt / tau_j)``, shape (n_lags,); ``dt`` defaults to :attr:`sample_time`."""
        step = self.sample_time if dt is None else _positive("dt", dt)
        return np.exp(-step / self.time_constants)

    def instantaneous_gain(self, dt: float | None = None) -> float:
        """``g = sum_j c_j (1 - a_j)``: how the current sample's output depends on its input."""
        return float(np.sum(self.weights * (1.0 - self.poles(dt))))

    def lags(
        self, u: object, dt: float | None = None, state: np.ndarray | None = None, rest: float | None = None
    ) -> np.ndarray:
        """Lag outputs ``s_j(k)``, shape (n_samples, n_lags), from ``state`` (default the term's;
        ``None``: at rest at ``rest``, default ``u[0]``)."""
        from scipy.signal import lfilter

        uu = np.asarray(u, dtype=float).reshape(-1)
        a = self.poles(dt)
        st = self.state if state is None else np.asarray(state, dtype=float).reshape(-1)
        out = np.empty((uu.size, a.size))
        if uu.size == 0:
            return out
        s0 = np.full(a.size, uu[0] if rest is None else float(rest)) if st is None else st
        for j, aj in enumerate(a):
            out[:, j] = lfilter([1.0 - aj], [1.0, -aj], uu, zi=[aj * s0[j]])[0]
        return out

    def run(self, u: object, dt: float | None = None, rest: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Creep output, shape (n_samples,), and the final lag outputs, shape (n_lags,).

        Parameters
        ----------
        u : array_like of shape (n_samples,)
            Input (model units, e.g. volts).
        dt : float, optional
            Sampling period [s]; default :attr:`sample_time`.
        rest : float, optional
            Input the lags rest at before the first sample when the term has no ``state``
            (default ``u[0]``).
        """
        S = self.lags(u, dt, rest=rest)
        if S.shape[0] == 0:
            final = np.array(self.state) if self.state is not None else np.zeros(self.n_lags)
            return np.zeros(0), final
        return S @ self.weights, S[-1].copy()

    def with_state(self, state: object | None) -> CreepTerm:
        """A copy with lag outputs ``state`` (``None``: at rest, see the module notes)."""
        return replace(self, state=state)

    def to_dict(self) -> dict[str, Any]:
        """The ``creep`` object of the ``stageid.hysteresis/1`` format."""
        return {
            "time_constants": self.time_constants.tolist(),
            "weights": self.weights.tolist(),
            "sample_time": self.sample_time,
            "state": None if self.state is None else self.state.tolist(),
        }

    @classmethod
    def from_dict(cls, d: object) -> CreepTerm:
        """Inverse of :meth:`to_dict`; raises :class:`ModelFormatError` on malformed fields."""
        if (
            not isinstance(d, dict)
            or not {"time_constants", "weights", "sample_time"} <= set(d)
            or not set(d) <= {"time_constants", "weights", "sample_time", "state"}
        ):
            raise ModelFormatError(
                f"`creep` must be an object with time_constants, weights, sample_time[, state]; got {d!r:.80}."
            )
        for key in ("time_constants", "weights") + (("state",) if d.get("state") is not None else ()):
            v = d[key]
            if not isinstance(v, list) or not all(is_real(e) for e in v):
                raise ModelFormatError(f"`creep.{key}` must be a list of numbers; got {shown(v)}.")
        dt = d["sample_time"]
        if not is_real(dt):
            raise ModelFormatError(f"`creep.sample_time` must be a number; got {shown(dt)}.")
        try:
            return cls(time_constants=d["time_constants"], weights=d["weights"], sample_time=dt, state=d.get("state"))
        except ModelError as exc:
            raise ModelFormatError(str(exc)) from None
