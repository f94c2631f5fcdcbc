"""The two LTI model objects: :class:`StateSpaceModel` and :class:`TransferMatrix`.

x(k+1) = A x(k) + B u(k),   y(k) = C x(k) + D u(k)        (discrete, ``dt`` > 0)
dx/dt  = A x(t) + B u(t),   y(t) = C x(t) + D u(t)        (continuous, ``dt`` is None)

Each converts into the other (``to_transfer``, ``to_statespace``), so both live in this module
(as scipy keeps its LTI classes in one ``_ltisys.py``); the numerical work is done by the
one-way functions of :mod:`~stageid.models.conversions` and :mod:`~stageid.models.minimal`,
and the file format sits above in :mod:`~stageid.models.serialization`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.linalg as sla

from .._errors import ModelError
from ..display import html_repr
from . import control_bridge as bridge
from . import conversions as cv
from ._kernels import simulate_discrete
from ._validate import (
    as_dt,
    as_matrix,
    as_names,
    as_sample_time,
    as_transfer_entries,
    check_response,
    check_same_dt,
    count_channels,
    frequency_variable,
    input_samples,
)
from .json_text import LTI_FORMAT, dumps
from .minimal import minimal_realization

__all__ = ["StateSpaceModel", "TransferMatrix"]


@dataclass(frozen=True, eq=False)
class StateSpaceModel:
    """A linear time-invariant state-space model with named inputs and outputs.

    Parameters
    ----------
    A : array_like of shape (n_states, n_states)
    B : array_like of shape (n_states, n_inputs)
    C : array_like of shape (n_outputs, n_states)
    D : array_like of shape (n_outputs, n_inputs)
    dt : float or None
        Sample time in seconds; ``None`` means continuous time.
    inputs, outputs : sequence of str, optional
        Channel names; default ``u1, ...`` and ``y1, ...``.

    Raises
    ------
    ModelError
        When the matrices do not fit together, e.g. "`B` must have shape (15, 3); got (5, 3).",
        or an entry is no finite real number (``bool`` and strings are refused).

    Examples
    --------
    >>> from stageid.models import StateSpaceModel
    >>> g = StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.1)
    >>> float(g.dc_gain()[0, 0])
    2.0
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float | None = None
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()

    def _repr_html_(self) -> str:
        return html_repr(self)

    def __post_init__(self) -> None:
        A = as_matrix("A", self.A, (None, None))
        n = A.shape[0]
        if A.shape[1] != n:
            raise ModelError(f"`A` must be square with shape (n, n); got {A.shape}.")
        m = count_channels(self.inputs, self.D, self.B, axis=1)
        p = count_channels(self.outputs, self.D, self.C, axis=0)
        B = as_matrix("B", self.B, (n, m))
        C = as_matrix("C", self.C, (p, n))
        D = as_matrix("D", self.D, (p, m))
        set_ = object.__setattr__
        set_(self, "A", A)
        set_(self, "B", B)
        set_(self, "C", C)
        set_(self, "D", D)
        set_(self, "dt", as_dt(self.dt))
        set_(self, "inputs", as_names("inputs", self.inputs, m, "u"))
        set_(self, "outputs", as_names("outputs", self.outputs, p, "y"))

    # ---------------------------------------------------------------- basics
    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    @property
    def n_inputs(self) -> int:
        return int(self.B.shape[1])

    @property
    def n_outputs(self) -> int:
        return int(self.C.shape[0])

    @property
    def is_discrete(self) -> bool:
        return self.dt is not None

    def with_names(self, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None) -> StateSpaceModel:
        """Return the same model with new channel names."""
        return replace(
            self,
            inputs=tuple(inputs) if inputs is not None else self.inputs,
            outputs=tuple(outputs) if outputs is not None else self.outputs,
        )

    def __repr__(self) -> str:
        kind = "continuous" if self.dt is None else f"dt={self.dt:g}"
        return (
            f"StateSpaceModel(n_states={self.n_states}, inputs={list(self.inputs)}, "
            f"outputs={list(self.outputs)}, {kind})"
        )

    # -------------------------------------------------------------- analysis
    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (rad/s for continuous models, z-plane for discrete)."""
        return np.linalg.eigvals(self.A) if self.n_states else np.zeros(0, dtype=complex)

    def zeros(self, minimal: bool = True) -> np.ndarray:
        """Transmission zeros: the invariant zeros (:func:`~stageid.models.conversions.invariant_zeros`)
        of the minimal realisation, so decoupling zeros of a non-minimal model are not reported.

        Parameters
        ----------
        minimal : bool
            ``False`` takes the realisation as it is (invariant zeros, decoupling zeros included):
            for a model already reduced with a chosen tolerance, whose poles and zeros must come
            from the same state dimension.
        """
        g = self.minimal() if minimal else self
        return cv.invariant_zeros(g.A, g.B, g.C, g.D)

    def is_stable(self, margin: float = 0.0) -> bool:
        """True when all poles lie strictly inside the unit circle / left half plane."""
        poles = self.poles()
        if poles.size == 0:
            return True
        if self.dt is None:
            return bool(np.all(poles.real < -margin))
        return bool(np.all(np.abs(poles) < 1.0 - margin))

    def dc_gain(self) -> np.ndarray:
        """Static gain, ndarray of shape (n_outputs, n_inputs).

        Raises ModelError when the model has a pole at s = 0 (z = 1).
        """
        n = self.n_states
        M = -self.A if self.dt is None else np.eye(n) - self.A
        if n and np.linalg.matrix_rank(M) < n:
            raise ModelError("the DC gain is infinite: the model has a pole at s = 0 (z = 1).")
        return self.D + (self.C @ np.linalg.solve(M, self.B) if n else 0.0)

    def frequency_response(self, freqs_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Complex response ``C (vI - A)^-1 B + D`` at the given frequencies in Hz.

        Returns
        -------
        ndarray of shape (n_freqs, n_outputs, n_inputs)
            ``v = j 2 pi f`` for continuous models, ``exp(j 2 pi f dt)`` for discrete ones;
            infinite at a frequency that is exactly a pole.
        """
        return cv.ss_response(self.A, self.B, self.C, self.D, frequency_variable(freqs_hz, self.dt))

    def markov_parameters(self, n_parameters: int) -> np.ndarray:
        """Impulse-response (Markov) parameters ``D, CB, CAB, ...`` of a discrete model.

        Returns ndarray of shape (n_parameters, n_outputs, n_inputs).
        """
        if self.dt is None:
            raise ModelError("Markov parameters are defined for discrete models; convert with c2d first.")
        out = np.empty((n_parameters, self.n_outputs, self.n_inputs))
        if n_parameters:
            out[0] = self.D
        AkB = self.B.copy()
        for k in range(1, n_parameters):
            out[k] = self.C @ AkB
            AkB = self.A @ AkB
        return out

    # ------------------------------------------------------------ simulation
    def simulate(self, u: np.ndarray, x0: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
        """Response to the input samples ``u``.

        Parameters
        ----------
        u : array_like of shape (n_samples, n_inputs) (or (n_samples,) for one input)
        x0 : array_like of shape (n_states,), optional
            Initial state (zero by default).
        dt : float, optional
            Sample time of ``u``; required for continuous models, which are simulated
            exactly under a zero-order hold. For discrete models it must equal ``self.dt``.

        Returns
        -------
        ndarray of shape (n_samples, n_outputs)

        Raises
        ------
        ModelError
            Bad input or sample time, or a response that diverges (an unstable model): the
            message names the sample where it left the floating-point range.
        """
        uu = input_samples(u, self.n_inputs)
        if not np.all(np.isfinite(uu)):
            raise ModelError("input contains NaN or inf.")
        model = self
        if self.dt is None:
            if dt is None:
                raise ModelError("a continuous model needs the sample time `dt` of the input to simulate.")
            model = self.c2d(dt, method="zoh")
        else:
            check_same_dt(dt, self.dt)
        x = np.zeros(self.n_states) if x0 is None else np.array(x0, dtype=float).reshape(-1)
        if x.shape != (self.n_states,):
            raise ModelError(f"`x0` must have shape ({self.n_states},); got {x.shape}.")
        with np.errstate(over="ignore", invalid="ignore"):  # divergence is reported below
            y, _ = simulate_discrete(model.A, model.B, model.C, model.D, uu, x)
        return check_response(y, self.poles(), self.dt) if not np.isfinite(y).all() else y

    # ------------------------------------------------------------ conversion
    def c2d(self, dt: float, method: str = "zoh") -> StateSpaceModel:
        """Discretise (``method`` = "zoh" or "tustin"); see :func:`stageid.models.c2d`."""
        cv.check_method(method)
        if self.dt is not None:
            raise ModelError(f"the model is already discrete (dt={self.dt:g} s).")
        dt = as_sample_time(dt)
        Ad, Bd, Cd, Dd = cv.c2d_matrices(self.A, self.B, self.C, self.D, dt, method)
        return replace(self, A=Ad, B=Bd, C=Cd, D=Dd, dt=dt)

    def d2c(self, method: str = "zoh") -> StateSpaceModel:
        """Continuous equivalent; see :func:`stageid.models.d2c`."""
        cv.check_method(method)
        if self.dt is None:
            raise ModelError("the model is already continuous.")
        if self.n_states == 0:
            return replace(self, dt=None)
        Ac, Bc, Cc, Dc = cv.d2c_matrices(self.A, self.B, self.C, self.D, self.dt, method)
        return replace(self, A=Ac, B=Bc, C=Cc, D=Dc, dt=None)

    def minimal(self, tol: float | None = None) -> StateSpaceModel:
        """Remove uncontrollable and unobservable states; see :func:`stageid.models.minimal_realization`."""
        return minimal_realization(self, tol)

    def to_transfer(self) -> TransferMatrix:
        """Return the equivalent :class:`~stageid.models.TransferMatrix` (minimal per entry)."""
        return TransferMatrix.from_statespace(self)

    def to_control(self) -> Any:
        """Return a ``control.StateSpace`` with the same matrices, sample time and labels."""
        return bridge.to_control_ss(self.A, self.B, self.C, self.D, self.dt, self.inputs, self.outputs)

    @classmethod
    def from_control(cls, sys: Any) -> StateSpaceModel:
        """Build from a python-control ``StateSpace`` (or anything ``control.ss`` accepts)."""
        return cls(*bridge.from_control_ss(sys))

    def to_dict(self) -> dict[str, Any]:
        """The ``stageid.lti/1`` dictionary (keys in file order)."""
        return {
            "format": LTI_FORMAT,
            "kind": "statespace",
            "dt": self.dt,
            "A": self.A.tolist(),
            "B": self.B.tolist(),
            "C": self.C.tolist(),
            "D": self.D.tolist(),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
        }

    def to_json(self) -> str:
        """The ``stageid.lti/1`` text (byte-stable: ``from_json(s).to_json() == s``)."""
        return dumps(self.to_dict())


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
        On ragged nesting, a zero denominator, an improper entry, or a coefficient that is
        no finite real number.

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

    def _repr_html_(self) -> str:
        return html_repr(self)

    def __post_init__(self) -> None:
        nums, dens = as_transfer_entries(self.num, self.den)
        p, m = len(nums), len(nums[0])
        set_ = object.__setattr__
        set_(self, "num", nums)
        set_(self, "den", dens)
        set_(self, "dt", as_dt(self.dt))
        set_(self, "inputs", as_names("inputs", self.inputs, m, "u"))
        set_(self, "outputs", as_names("outputs", self.outputs, p, "y"))

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
        """Complex response at ``freqs_hz``; ndarray of shape (n_freqs, n_outputs, n_inputs).

        Infinite or NaN only where a frequency is exactly a pole; high orders do not overflow.
        """
        v = frequency_variable(freqs_hz, self.dt)
        out = np.empty((v.size, self.n_outputs, self.n_inputs), dtype=complex)
        for i in range(self.n_outputs):
            for j in range(self.n_inputs):
                out[:, i, j] = cv.rational_response(self.num[i][j], self.den[i][j], v)
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
        return np.roots(cv.strip_leading_zeros(np.asarray(self.den[output][input])))

    def entry_zeros(self, output: int, input: int) -> np.ndarray:
        """Roots of the numerator of one entry."""
        num = cv.strip_leading_zeros(np.asarray(self.num[output][input]))
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
        continuous ones are simulated through their state-space form under ZOH.  A response
        that diverges (an unstable model) raises ModelError naming the sample.
        """
        uu = input_samples(u, self.n_inputs)
        if self.dt is None:
            return self.to_statespace(minimal=False).simulate(uu, dt=dt)
        check_same_dt(dt, self.dt)
        y = cv.filter_entries(self.num, self.den, uu)
        if not np.isfinite(y).all():
            poles = [self.entry_poles(i, j) for i in range(self.n_outputs) for j in range(self.n_inputs)]
            return check_response(y, np.concatenate(poles), self.dt)
        return y

    # ------------------------------------------------------------ conversion
    def to_statespace(self, minimal: bool = True) -> StateSpaceModel:
        """A state-space realisation: one controllable-canonical block per entry, then
        (by default) reduced to a minimal realisation."""
        A, B, C, D = cv.tf2ss(self.num, self.den)
        if minimal and A.shape[0]:
            # balanced first: a continuous entry's companion block carries coefficients up to w^n
            # (~1e12 for a third-order coupling at 2000 rad/s), and the minimal realisation's
            # threshold, relative to that norm, called every state of such a plant unobservable
            A, scaling = sla.matrix_balance(A, permute=False)
            d = np.diag(scaling)
            B, C = B / d[:, None], C * d[None, :]
        model = StateSpaceModel(A, B, C, D, self.dt, self.inputs, self.outputs)
        return model.minimal() if minimal else model

    @classmethod
    def from_statespace(cls, model: StateSpaceModel) -> TransferMatrix:
        """Entry-wise transfer functions of a state-space model, each from a minimal SISO realisation."""
        num, den = cv.ss2tf(model.A, model.B, model.C, model.D)
        return cls(num, den, model.dt, model.inputs, model.outputs)

    def map_entries(self, fn: Callable[[StateSpaceModel], StateSpaceModel]) -> TransferMatrix:
        """Apply a state-space operation (e.g. c2d) to every SISO entry and rebuild the matrix."""
        num, den, dt = [], [], None
        for i in range(self.n_outputs):
            nrow, drow = [], []
            for j in range(self.n_inputs):
                a, b, c, d = cv.tf2ss_siso(self.num[i][j], self.den[i][j])
                g = fn(StateSpaceModel(a, b, c, d, self.dt))
                dt = g.dt
                t = TransferMatrix.from_statespace(g)
                nrow.append(t.num[0][0])
                drow.append(t.den[0][0])
            num.append(nrow)
            den.append(drow)
        return replace(self, num=num, den=den, dt=dt)

    def c2d(self, dt: float, method: str = "zoh") -> TransferMatrix:
        """Discretise every entry (``method`` = "zoh" or "tustin"); see :func:`stageid.models.c2d`."""
        cv.check_method(method)
        return self.map_entries(lambda g: g.c2d(dt, method))

    def d2c(self, method: str = "zoh") -> TransferMatrix:
        """Continuous equivalent of every entry; see :func:`stageid.models.d2c`."""
        cv.check_method(method)
        return self.map_entries(lambda g: g.d2c(method))

    def to_control(self) -> Any:
        """Return a ``control.TransferFunction`` with the same coefficients and labels."""
        return bridge.to_control_tf(self.num, self.den, self.dt, self.inputs, self.outputs)

    @classmethod
    def from_control(cls, sys: Any) -> TransferMatrix:
        """Build from a python-control ``TransferFunction`` (or a StateSpace, converted entry-wise)."""
        if bridge.is_control_ss(sys):
            return cls.from_statespace(StateSpaceModel.from_control(sys))
        return cls(*bridge.from_control_tf(sys))

    def to_dict(self) -> dict[str, Any]:
        """The ``stageid.lti/1`` dictionary (keys in file order)."""
        return {
            "format": LTI_FORMAT,
            "kind": "transfer",
            "dt": self.dt,
            "num": [[e.tolist() for e in row] for row in self.num],
            "den": [[e.tolist() for e in row] for row in self.den],
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
        }

    def to_json(self) -> str:
        """The ``stageid.lti/1`` text (byte-stable)."""
        return dumps(self.to_dict())
