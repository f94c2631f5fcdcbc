"""Classical and modified Prandtl-Ishlinskii (PI) hysteresis models.

Classical PI model
    ``y(k) = y0 + sum_i w_i H_{r_i}[x - xc](k)``, a weighted sum of play operators (eq. 1)
    acting on the input ``x`` measured from the centre ``xc``.  The operator with threshold
    ``r = 0`` is the identity, so its weight is the linear term ``p0 x`` of the PI model.

Modified PI model (eq. 4)
    ``y(k) = y0 + sum_i w_i H_i[x - xc; r_i, rc_i, ra_i, rb_i](k)``, the same sum over
    coupled-play operators (eq. 3, read as in :mod:`stageid.hysteresis.models.operators`).  With
    ``rc = ra = rb = r`` it is the classical PI model.

Both models are immutable and carry their operator state (last input, operator outputs),
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

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..._errors import ModelError
from ...display import html_repr, short_repr
from .common import as_input
from .creep import CreepTerm
from .operators import OperatorState, check_cp_thresholds, gamma_down, gamma_up

__all__ = ["PIModel", "ModifiedPIModel", "HYSTERESIS_FORMAT", "STATE_KINDS"]

HYSTERESIS_FORMAT = "stageid.hysteresis/1"
STATE_KINDS = ("zero", "ascending", "descending")


def _vec(name: str, value: object, n: int | None = None) -> np.ndarray:
    arr = np.array(value, dtype=float, copy=True).reshape(-1)
    if n is not None and arr.size != n:
        raise ModelError(f"`{name}` must have {n} entries (one per operator); got {arr.size}.")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"`{name}` must be finite; got {arr.tolist()}.")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class _PIBase:
    r: np.ndarray
    weights: np.ndarray
    input_offset: float = 0.0
    output_offset: float = 0.0
    state: OperatorState | None = None
    inputs: tuple[str, ...] = ("V",)
    outputs: tuple[str, ...] = ("y",)
    input_limits: tuple[float, float] | None = None

    kind = ""

    def _init_common(self) -> None:
        r = _vec("r", self.r)
        if r.size == 0:
            raise ModelError("a PI model needs at least one operator; got 0 thresholds.")
        if np.any(r < 0):
            raise ModelError(f"thresholds `r` must be >= 0; got {r.tolist()}.")
        w = _vec("weights", self.weights, r.size)
        set_ = object.__setattr__
        set_(self, "r", r)
        set_(self, "weights", w)
        for name in ("input_offset", "output_offset"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise ModelError(f"`{name}` must be finite; got {v}.")
            set_(self, name, v)
        st = self.state if self.state is not None else OperatorState.zeros(r.size)
        if not isinstance(st, OperatorState):
            raise ModelError(f"`state` must be an OperatorState; got {type(st).__name__}.")
        if st.z.size != r.size:
            raise ModelError(f"`state` must hold {r.size} operator outputs; got {st.z.size}.")
        set_(self, "state", st)
        for name in ("inputs", "outputs"):
            names = tuple(
                str(s)
                for s in ((getattr(self, name),) if isinstance(getattr(self, name), str) else getattr(self, name))
            )
            if len(names) != 1:
                raise ModelError(f"a hysteresis model has exactly one {name[:-1]} name; got {list(names)}.")
            set_(self, name, names)
        creep = getattr(self, "creep", None)
        if creep is not None:
            if not isinstance(creep, CreepTerm):
                raise ModelError(f"`creep` must be a CreepTerm or None; got {type(creep).__name__}.")
        if self.input_limits is not None:
            lim = tuple(float(v) for v in self.input_limits)
            if len(lim) != 2 or not (np.isfinite(lim[0]) and np.isfinite(lim[1]) and lim[0] < lim[1]):
                raise ModelError(f"`input_limits` must be (low, high) with low < high; got {self.input_limits!r}.")
            set_(self, "input_limits", lim)

    # ------------------------------------------------------------------ operator bank
    @property
    def n_operators(self) -> int:
        """Number of operators."""
        return int(self.r.size)

    @property
    def n_states(self) -> int:  # for generic code that asks models for their order
        return self.n_operators

    def coupled_play_thresholds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(r, rc, ra, rb)`` of the operators read as coupled plays (eq. 3); a play is the
        coupled play with ``rc = ra = rb = r``."""
        raise NotImplementedError

    def to_operator_input(self, u: np.ndarray | float) -> np.ndarray:
        """Operator coordinates of model inputs: ``u - input_offset`` (warped for a modified PI
        model with ``input_warp``, see :class:`ModifiedPIModel`)."""
        return np.asarray(u, dtype=float) - self.input_offset

    def from_operator_input(self, x: np.ndarray | float) -> np.ndarray:
        """Model inputs from operator coordinates (inverse of :meth:`to_operator_input`)."""
        return np.asarray(x, dtype=float) + self.input_offset

    def _warp_slope(self) -> float:
        return 1.0

    def boundaries(self, x: float) -> tuple[np.ndarray, np.ndarray]:
        """Ascending and descending boundary values of every operator at operator input ``x``."""
        r, rc, ra, rb = self.coupled_play_thresholds()
        return gamma_up(x, r, rc), gamma_down(x, ra, rb)

    def consistent_state(self, u0: float, kind: str = "zero") -> OperatorState:
        """A state consistent with the input value ``u0`` (model units).

        ``"zero"``: the letter's ``x0 = z0 = 0`` followed by a jump to ``u0`` (eq. 2);
        ``"ascending"``: arrived at ``u0`` rising from far below (every operator on its
        ascending boundary); ``"descending"``: arrived falling from far above.
        """
        if kind not in STATE_KINDS:
            raise ModelError(f"state kind must be one of {', '.join(STATE_KINDS)}; got {kind!r}.")
        x = float(self.to_operator_input(float(u0)))
        up, down = self.boundaries(x)
        if kind == "ascending":
            z = up
        elif kind == "descending":
            z = down
        else:
            z = np.maximum(up, np.minimum(down, 0.0))
        return OperatorState(x, z)

    def with_state(self, state: OperatorState | None) -> _PIBase:
        """A copy of the model starting from ``state`` (``None``: the zero state)."""
        return replace(self, state=state)

    def operator_outputs(self, u: object) -> tuple[np.ndarray, OperatorState]:
        """Outputs of every operator, shape (n_samples, n_operators), and the final state."""
        from .. import kernels  # numba: imported on first use

        x = np.ascontiguousarray(self.to_operator_input(as_input(u, self.inputs[0])))
        r, rc, ra, rb = self.coupled_play_thresholds()
        if self.kind == "pi":
            z, zf = kernels.play_bank(x, r, np.array(self.state.z))
        else:
            z, zf = kernels.cp_bank(x, r, rc, ra, rb, np.array(self.state.z))
        return z, OperatorState(float(x[-1]) if x.size else self.state.x, zf)

    def run(self, u: object, dt: float | None = None) -> tuple[np.ndarray, OperatorState]:
        """Simulate from the model's state; returns y of shape (n_samples, 1) and the final state.

        ``dt`` [s] is used only by a creep term (default its ``sample_time``); the final state
        is the operator state (a creep term's final lags: ``model.creep.run(u, dt)[1]``).
        """
        from .. import kernels  # numba: imported on first use

        u_in = as_input(u, self.inputs[0])
        x = np.ascontiguousarray(self.to_operator_input(u_in))
        r, rc, ra, rb = self.coupled_play_thresholds()
        z0 = np.array(self.state.z)
        if self.kind == "pi":
            y, zf = kernels.play_sum_auto(x, r, self.weights, z0, self.state.x)
        else:
            up, down = gamma_up(self.state.x, r, rc), gamma_down(self.state.x, ra, rb)
            if np.all(up <= z0) and np.all(z0 <= down):  # a consistent state: events are exact
                y, zf = kernels.cp_sum_auto(x, r, rc, ra, rb, self.weights, z0, self.state.x)
            else:
                y, zf = kernels.cp_sum(x, r, rc, ra, rb, self.weights, z0)
        creep = getattr(self, "creep", None)
        if creep is not None and u_in.size:
            y = y + creep.run(u_in, dt)[0]  # no creep state: at rest at the first input
        return (y + self.output_offset)[:, None], OperatorState(float(x[-1]) if x.size else self.state.x, zf)

    def simulate(self, u: object, dt: float | None = None) -> np.ndarray:
        """Model output for an input record, starting from the model's state.

        Parameters
        ----------
        u : array_like of shape (n_samples, 1) or (n_samples,)
            Input samples (e.g. volts).
        dt : float, optional
            Sampling period [s].  Ignored by the rate-independent model; used by an optional
            ``creep`` term (default: the creep term's ``sample_time``).

        Returns
        -------
        ndarray of shape (n_samples, 1)

        Raises
        ------
        ModelError
            If ``u`` has the wrong shape or is not finite.

        Examples
        --------
        >>> from stageid.hysteresis import PIModel
        >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
        >>> m.simulate([0.0, 2.0, 1.0])[:, 0].tolist()
        [0.0, 2.5, 1.5]
        """
        return self.run(u, dt)[0]

    # ------------------------------------------------------------------ properties
    def min_slope(self) -> float:
        """A lower bound of dy/dx over all states: ``w_0 + sum min(w_i, 0)`` (see module notes)."""
        order = np.argsort(self.r, kind="stable")
        w = self.weights[order]
        return (
            float(w[0] + np.sum(np.minimum(w[1:], 0.0)))
            if self.r[order][0] == 0.0
            else float(np.sum(np.minimum(w, 0.0)))
        )

    def min_input_slope(self) -> float:
        """A lower bound of dy/du (model input units): :meth:`min_slope` times the warp's least slope."""
        return self.min_slope() * self._warp_slope()

    def _base_dict(self) -> dict[str, Any]:
        return {
            "format": HYSTERESIS_FORMAT,
            "kind": self.kind,
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "input_offset": self.input_offset,
            "output_offset": self.output_offset,
        }

    def _tail_dict(self) -> dict[str, Any]:
        d = {
            "weights": self.weights.tolist(),
            "state": {"x": self.state.x, "z": self.state.z.tolist()},
            "input_limits": None if self.input_limits is None else list(self.input_limits),
        }
        creep = getattr(self, "creep", None)
        if creep is not None:  # optional field: models without creep write exactly the old format
            d["creep"] = creep.to_dict()
        return d


@dataclass(frozen=True, eq=False)
class PIModel(_PIBase):
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


@dataclass(frozen=True, eq=False)
class ModifiedPIModel(_PIBase):
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
        r = _vec("r", self.r)
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
