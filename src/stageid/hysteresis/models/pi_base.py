"""The part every Prandtl-Ishlinskii model shares (:mod:`.pi`, :mod:`.modified_pi`).

Thresholds and weights of the operator bank, the input and output offsets, the operator
state (``x`` in operator coordinates: input minus ``input_offset``, warped for a modified PI
model with ``input_warp``), the run over an input, optional creep, the monotonicity bound
``w_0 + sum_{i>=1} min(w_i, 0)`` and the fields of the ``stageid.hysteresis/1`` format.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..._errors import ModelError
from .common import as_input
from .creep import CreepTerm
from .operators import OperatorState, gamma_down, gamma_up

__all__ = ["PIBase", "operator_vector", "HYSTERESIS_FORMAT", "STATE_KINDS"]

HYSTERESIS_FORMAT = "stageid.hysteresis/1"
STATE_KINDS = ("zero", "ascending", "descending")


def operator_vector(name: str, value: object, n: int | None = None) -> np.ndarray:
    """``value`` as a read-only finite float vector (of ``n`` entries, one per operator, when given)."""
    arr = np.array(value, dtype=float, copy=True).reshape(-1)
    if n is not None and arr.size != n:
        raise ModelError(f"`{name}` must have {n} entries (one per operator); got {arr.size}.")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"`{name}` must be finite; got {arr.tolist()}.")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class PIBase:
    """What every PI model shares: thresholds, weights, offsets, the operator state and names,
    the operator bank and its run, the monotonicity bound and the common file fields; the
    subclasses say which operators (:class:`~.pi.PIModel`, :class:`~.modified_pi.ModifiedPIModel`)."""

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
        r = operator_vector("r", self.r)
        if r.size == 0:
            raise ModelError("a PI model needs at least one operator; got 0 thresholds.")
        if np.any(r < 0):
            raise ModelError(f"thresholds `r` must be >= 0; got {r.tolist()}.")
        w = operator_vector("weights", self.weights, r.size)
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

    def with_state(self, state: OperatorState | None) -> PIBase:
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
