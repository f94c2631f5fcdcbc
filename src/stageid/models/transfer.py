"""Immutable MIMO transfer matrices: one numerator/denominator pair per (output, input)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._errors import ModelError
from ._validate import as_dt, as_names, frequency_variable
from .statespace import StateSpaceModel

__all__ = ["TransferMatrix"]


def _as_poly(field: str, i: int, j: int, value: object, error: type[ModelError]) -> np.ndarray:
    if isinstance(value, str):
        raise error(f"`{field}[{i}][{j}]` must be a list of numbers; got a string.")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise error(f"`{field}[{i}][{j}]` must be a list of numbers; got {value!r}.") from None
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or arr.size == 0:
        raise error(f"`{field}[{i}][{j}]` must be a non-empty 1-D list of coefficients; got shape {arr.shape}.")
    if not np.all(np.isfinite(arr)):
        raise error(f"`{field}[{i}][{j}]` must contain only finite numbers.")
    arr.setflags(write=False)
    return arr


def _strip(poly: np.ndarray) -> np.ndarray:
    nz = np.flatnonzero(poly)
    return poly[nz[0] :] if nz.size else poly[-1:]


@dataclass(frozen=True, eq=False)
class TransferMatrix:
    """A MIMO transfer matrix ``G[i][j](v) = num[i][j](v) / den[i][j](v)``.

    Coefficients are in descending powers of ``s`` (continuous, ``dt`` is None) or ``z``
    (discrete), exactly as in the ``stageid.lti/1`` format.

    Parameters
    ----------
    num, den : nested sequences [n_outputs][n_inputs] of 1-D coefficient arrays
    dt : float or None
    inputs, outputs : sequence of str, optional

    Raises
    ------
    ModelError
        On ragged nesting, a zero denominator or an improper entry.

    Examples
    --------
    >>> from stageid.models import TransferMatrix
    >>> g = TransferMatrix([[[1.0]]], [[[1.0, 1.0]]])          # 1 / (s + 1)
    >>> complex(g.frequency_response([0.0])[0, 0, 0])
    (1+0j)
    """

    num: Any
    den: Any
    dt: float | None = None
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self._init_fields(ModelError)

    def _init_fields(self, error: type[ModelError]) -> None:
        num, den = self.num, self.den
        if isinstance(num, np.ndarray) and num.ndim == 1:
            num = [[num]]
        if isinstance(den, np.ndarray) and den.ndim == 1:
            den = [[den]]
        for field, val in (("num", num), ("den", den)):
            if (
                not isinstance(val, (list, tuple, np.ndarray))
                or len(val) == 0
                or any(not isinstance(row, (list, tuple, np.ndarray)) or len(row) == 0 for row in val)
            ):
                raise error(f"`{field}` must be nested as [output][input][coefficient]; got {type(val).__name__}.")
        p = len(num)
        m = len(num[0])
        for field, val in (("num", num), ("den", den)):
            shape = (len(val), *{len(row) for row in val})
            if len(val) != p or any(len(row) != m for row in val):
                raise error(f"`{field}` must have shape ({p}, {m}) entries ([output][input]); got {shape}.")
        nums = tuple(tuple(_as_poly("num", i, j, num[i][j], error) for j in range(m)) for i in range(p))
        dens = tuple(tuple(_as_poly("den", i, j, den[i][j], error) for j in range(m)) for i in range(p))
        for i in range(p):
            for j in range(m):
                d = _strip(dens[i][j])
                if not np.any(d):
                    raise error(f"`den[{i}][{j}]` is zero.")
                if _strip(nums[i][j]).size > d.size and np.any(nums[i][j]):
                    raise error(
                        f"entry [{i}][{j}] is improper: numerator degree {_strip(nums[i][j]).size - 1} exceeds "
                        f"denominator degree {d.size - 1}."
                    )
        set_ = object.__setattr__
        set_(self, "num", nums)
        set_(self, "den", dens)
        set_(self, "dt", as_dt(self.dt, error))
        set_(self, "inputs", as_names("inputs", self.inputs, m, "u", error))
        set_(self, "outputs", as_names("outputs", self.outputs, p, "y", error))

    # ---------------------------------------------------------------- basics
    @property
    def n_inputs(self) -> int:
        return len(self.num[0])

    @property
    def n_outputs(self) -> int:
        return len(self.num)

    @property
    def is_discrete(self) -> bool:
        return self.dt is not None

    def __repr__(self) -> str:
        kind = "continuous" if self.dt is None else f"dt={self.dt:g}"
        return f"TransferMatrix(inputs={list(self.inputs)}, outputs={list(self.outputs)}, {kind})"

    def entry(self, output: int | str, input: int | str) -> TransferMatrix:
        """The SISO transfer function from ``input`` to ``output`` (index or name)."""
        i = self.outputs.index(output) if isinstance(output, str) else int(output)
        j = self.inputs.index(input) if isinstance(input, str) else int(input)
        return TransferMatrix([[self.num[i][j]]], [[self.den[i][j]]], self.dt, (self.inputs[j],), (self.outputs[i],))

    # -------------------------------------------------------------- analysis
    def frequency_response(self, freqs_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Complex response at ``freqs_hz``; ndarray of shape (n_freqs, n_outputs, n_inputs)."""
        v = frequency_variable(freqs_hz, self.dt)
        out = np.empty((v.size, self.n_outputs, self.n_inputs), dtype=complex)
        for i in range(self.n_outputs):
            for j in range(self.n_inputs):
                out[:, i, j] = np.polyval(self.num[i][j], v) / np.polyval(self.den[i][j], v)
        return out

    def dc_gain(self) -> np.ndarray:
        """Static gain, ndarray of shape (n_outputs, n_inputs); ModelError for a pole at DC."""
        v = 0.0 if self.dt is None else 1.0
        out = np.empty((self.n_outputs, self.n_inputs))
        for i in range(self.n_outputs):
            for j in range(self.n_inputs):
                d = np.polyval(self.den[i][j], v)
                n = np.polyval(self.num[i][j], v)
                if abs(d) <= 1e-14 * max(1.0, np.max(np.abs(self.den[i][j]))):
                    if abs(n) > 1e-14:
                        raise ModelError(f"the DC gain of entry [{i}][{j}] is infinite: it has a pole at DC.")
                    raise ModelError(f"entry [{i}][{j}] is 0/0 at DC: cancel the common root first.")
                out[i, j] = n / d
        return out

    def poles(self) -> np.ndarray:
        """Poles of the minimal realisation of the whole matrix (shared poles counted once)."""
        return self.to_statespace().poles()

    def entry_poles(self, output: int, input: int) -> np.ndarray:
        """Roots of the denominator of one entry."""
        return np.roots(_strip(np.asarray(self.den[output][input])))

    def entry_zeros(self, output: int, input: int) -> np.ndarray:
        """Roots of the numerator of one entry."""
        num = _strip(np.asarray(self.num[output][input]))
        return np.roots(num) if np.any(num) else np.zeros(0, dtype=complex)

    def zeros(self) -> np.ndarray:
        """Invariant zeros of the minimal realisation (numerator roots for SISO)."""
        if self.n_inputs == self.n_outputs == 1:
            return self.entry_zeros(0, 0)
        return self.to_statespace().zeros()

    def is_stable(self) -> bool:
        return self.to_statespace().is_stable()

    # ------------------------------------------------------------ simulation
    def simulate(self, u: np.ndarray, dt: float | None = None) -> np.ndarray:
        """Response to ``u`` of shape (n_samples, n_inputs), from rest.

        Discrete models are filtered entry by entry (exact difference equations);
        continuous ones are simulated through their state-space form under ZOH.
        """
        uu = np.array(u, dtype=float)
        if uu.ndim == 1:
            uu = uu[:, None]
        if uu.ndim != 2 or uu.shape[1] != self.n_inputs:
            raise ModelError(f"input must have shape (n_samples, {self.n_inputs}); got {tuple(np.shape(u))}.")
        if self.dt is None:
            return self.to_statespace(minimal=False).simulate(uu, dt=dt)
        if dt is not None and not np.isclose(dt, self.dt, rtol=1e-6, atol=0):
            raise ModelError(f"the input's sample time {dt:g} s differs from the model's {self.dt:g} s.")
        y = np.zeros((uu.shape[0], self.n_outputs))
        for i in range(self.n_outputs):
            for j in range(self.n_inputs):
                den = _strip(np.asarray(self.den[i][j]))
                num = _strip(np.asarray(self.num[i][j]))
                num = np.concatenate([np.zeros(den.size - num.size), num])
                y[:, i] += _signal().lfilter(num, den, uu[:, j])
        return y

    # ------------------------------------------------------------ conversion
    def to_statespace(self, minimal: bool = True) -> StateSpaceModel:
        """A state-space realisation: one controllable-canonical block per entry, then
        (by default) reduced to a minimal realisation."""
        blocks = []
        for i in range(self.n_outputs):
            for j in range(self.n_inputs):
                blocks.append((i, j, _siso_ss(self.num[i][j], self.den[i][j])))
        n = sum(b[2][0].shape[0] for b in blocks)
        A = np.zeros((n, n))
        B = np.zeros((n, self.n_inputs))
        C = np.zeros((self.n_outputs, n))
        D = np.zeros((self.n_outputs, self.n_inputs))
        k = 0
        for i, j, (a, b, c, d) in blocks:
            r = a.shape[0]
            A[k : k + r, k : k + r] = a
            B[k : k + r, j] = b[:, 0]
            C[i, k : k + r] = c[0]
            D[i, j] = d[0, 0]
            k += r
        model = StateSpaceModel(A, B, C, D, self.dt, self.inputs, self.outputs)
        return model.minimal() if minimal else model

    @classmethod
    def from_statespace(cls, model: StateSpaceModel) -> TransferMatrix:
        """Entry-wise transfer functions of a state-space model, each from a minimal SISO realisation."""
        num, den = [], []
        for i in range(model.n_outputs):
            nrow, drow = [], []
            for j in range(model.n_inputs):
                siso = StateSpaceModel(model.A, model.B[:, [j]], model.C[[i]], model.D[[i]][:, [j]], model.dt).minimal()
                if siso.n_states == 0:
                    nrow.append(np.array([siso.D[0, 0]]))
                    drow.append(np.array([1.0]))
                    continue
                b, a = _signal().ss2tf(siso.A, siso.B, siso.C, siso.D)
                nrow.append(np.real_if_close(b[0]).astype(float))
                drow.append(np.real_if_close(a).astype(float))
            num.append(nrow)
            den.append(drow)
        return cls(num, den, model.dt, model.inputs, model.outputs)

    def map_entries(self, fn: Callable[[StateSpaceModel], StateSpaceModel]) -> TransferMatrix:
        """Apply a state-space operation (e.g. c2d) to every SISO entry and rebuild the matrix."""
        num, den, dt = [], [], None
        for i in range(self.n_outputs):
            nrow, drow = [], []
            for j in range(self.n_inputs):
                a, b, c, d = _siso_ss(self.num[i][j], self.den[i][j])
                g = fn(StateSpaceModel(a, b, c, d, self.dt))
                dt = g.dt
                t = TransferMatrix.from_statespace(g)
                nrow.append(t.num[0][0])
                drow.append(t.den[0][0])
            num.append(nrow)
            den.append(drow)
        return replace(self, num=num, den=den, dt=dt)

    def c2d(self, dt: float, method: str = "zoh") -> TransferMatrix:
        from .discretization import c2d

        return c2d(self, dt, method)

    def d2c(self, method: str = "zoh") -> TransferMatrix:
        from .discretization import d2c

        return d2c(self, method)

    def to_control(self) -> Any:
        """Return a ``control.TransferFunction`` with the same coefficients and labels."""
        import control

        return control.tf(
            [[list(e) for e in row] for row in self.num],
            [[list(e) for e in row] for row in self.den],
            0 if self.dt is None else self.dt,
            inputs=list(self.inputs),
            outputs=list(self.outputs),
        )

    @classmethod
    def from_control(cls, sys: Any) -> TransferMatrix:
        """Build from a python-control ``TransferFunction`` (or a StateSpace, converted entry-wise)."""
        import control

        from .statespace import _dt_from_control

        if isinstance(sys, control.StateSpace):
            return cls.from_statespace(StateSpaceModel.from_control(sys))
        if not isinstance(sys, control.TransferFunction):
            sys = control.tf(sys)
        num = [[np.asarray(sys.num_list[i][j], dtype=float) for j in range(sys.ninputs)] for i in range(sys.noutputs)]
        den = [[np.asarray(sys.den_list[i][j], dtype=float) for j in range(sys.ninputs)] for i in range(sys.noutputs)]
        return cls(num, den, _dt_from_control(sys.dt), tuple(sys.input_labels), tuple(sys.output_labels))

    def to_dict(self) -> dict[str, Any]:
        from .serialization import lti_to_dict

        return lti_to_dict(self)

    def to_json(self) -> str:
        from .serialization import dumps

        return dumps(self.to_dict())


def _signal():
    """scipy.signal, imported on first use (it costs about a second at start-up)."""
    import scipy.signal

    return scipy.signal


def _siso_ss(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    d = _strip(np.asarray(den, dtype=float))
    n = _strip(np.asarray(num, dtype=float))
    if d.size == 1:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[n[-1] / d[0] if n.size == 1 else 0.0]])
    if not np.any(n):
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.zeros((1, 1))
    a, b, c, dd = _signal().tf2ss(n, d)
    return a, b, c, dd
