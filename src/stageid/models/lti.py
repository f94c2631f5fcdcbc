"""The two LTI model objects: :class:`StateSpaceModel` and :class:`TransferMatrix`.

x(k+1) = A x(k) + B u(k),   y(k) = C x(k) + D u(k)        (discrete, ``dt`` > 0)
dx/dt  = A x(t) + B u(t),   y(t) = C x(t) + D u(t)        (continuous, ``dt`` is None)

Each converts into the other (``to_transfer``, ``to_statespace``), so both live in this module
(as scipy keeps its LTI classes in one ``_ltisys.py``); the numerical work is done by the
one-way functions of :mod:`~stageid.models.conversions` and :mod:`~stageid.models.minimal`,
the time responses by :mod:`~stageid.models.simulation`, and the file format sits above in
:mod:`~stageid.models.serialization`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._errors import ModelError
from ..display import HtmlRepr
from . import control_bridge as bridge
from . import conversions as cv
from ._validate import as_sample_time, frequency_variable, statespace_fields, transfer_fields
from .json_text import dumps, lti_dict
from .minimal import minimal_realization
from .simulation import simulate_statespace, simulate_transfer

__all__ = ["StateSpaceModel", "TransferMatrix"]


@dataclass(frozen=True, eq=False)
class StateSpaceModel(HtmlRepr):
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

    def __post_init__(self) -> None:
        fields = statespace_fields(self.A, self.B, self.C, self.D, self.dt, self.inputs, self.outputs)
        for name, value in fields.items():
            object.__setattr__(self, name, value)

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
        return cv.poles_stable(self.poles(), self.dt, margin)

    def dc_gain(self) -> np.ndarray:
        """Static gain, ndarray of shape (n_outputs, n_inputs).

        Raises ModelError when the model has a pole at s = 0 (z = 1).
        """
        return cv.ss_dc_gain(self.A, self.B, self.C, self.D, self.dt)

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
        return cv.markov_parameters(self.A, self.B, self.C, self.D, n_parameters)

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
        return simulate_statespace(self, u, x0, dt)

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
        arrays = {"A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(), "D": self.D.tolist()}
        return lti_dict("statespace", self.dt, arrays, self.inputs, self.outputs)

    def to_json(self) -> str:
        """The ``stageid.lti/1`` text (byte-stable: ``from_json(s).to_json() == s``)."""
        return dumps(self.to_dict())


@dataclass(frozen=True, eq=False)
class TransferMatrix(HtmlRepr):
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

    def __post_init__(self) -> None:
        for name, value in transfer_fields(self.num, self.den, self.dt, self.inputs, self.outputs).items():
            object.__setattr__(self, name, value)

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
        return cv.transfer_response(self.num, self.den, frequency_variable(freqs_hz, self.dt))

    def dc_gain(self) -> np.ndarray:
        """Static gain, ndarray of shape (n_outputs, n_inputs); ModelError for a pole at DC."""
        return cv.transfer_dc_gain(self.num, self.den, self.dt)

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
        return simulate_transfer(self, u, dt)

    # ------------------------------------------------------------ conversion
    def to_statespace(self, minimal: bool = True) -> StateSpaceModel:
        """A state-space realisation: one controllable-canonical block per entry, then
        (by default) reduced to a minimal realisation."""
        A, B, C, D = cv.tf2ss(self.num, self.den)
        if minimal:
            A, B, C = cv.balanced(A, B, C)
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
        coefficients = {key: [[e.tolist() for e in row] for row in getattr(self, key)] for key in ("num", "den")}
        return lti_dict("transfer", self.dt, coefficients, self.inputs, self.outputs)

    def to_json(self) -> str:
        """The ``stageid.lti/1`` text (byte-stable)."""
        return dumps(self.to_dict())
