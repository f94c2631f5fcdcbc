"""Immutable MIMO state-space models, discrete or continuous.

x(k+1) = A x(k) + B u(k),   y(k) = C x(k) + D u(k)        (discrete, ``dt`` > 0)
dx/dt  = A x(t) + B u(t),   y(t) = C x(t) + D u(t)        (continuous, ``dt`` is None)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._errors import ModelError
from ._kernels import simulate_discrete
from ._validate import as_dt, as_matrix, as_names, frequency_variable

__all__ = ["StateSpaceModel"]


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
        When the matrices do not fit together, e.g. "`B` must have shape (15, 3); got (5, 3)."

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
        self._init_fields(ModelError)

    def _init_fields(self, error: type[ModelError]) -> None:
        A = as_matrix("A", self.A, (None, None), error)
        n = A.shape[0]
        if A.shape[1] != n:
            raise error(f"`A` must be square with shape (n, n); got {A.shape}.")
        m = _count(self.inputs, self.D, self.B, axis=1)
        p = _count(self.outputs, self.D, self.C, axis=0)
        B = as_matrix("B", self.B, (n, m), error)
        C = as_matrix("C", self.C, (p, n), error)
        D = as_matrix("D", self.D, (p, m), error)
        set_ = object.__setattr__
        set_(self, "A", A)
        set_(self, "B", B)
        set_(self, "C", C)
        set_(self, "D", D)
        set_(self, "dt", as_dt(self.dt, error))
        set_(self, "inputs", as_names("inputs", self.inputs, m, "u", error))
        set_(self, "outputs", as_names("outputs", self.outputs, p, "y", error))

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

    def with_names(
        self, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None
    ) -> StateSpaceModel:
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
        """Transmission zeros: finite generalised eigenvalues of the Rosenbrock pencil of the
        minimal realisation (so decoupling zeros of a non-minimal model are not reported).

        For a non-square system the zeros are those shared by two random square
        compressions of the pencil (generically exactly the invariant zeros).

        Parameters
        ----------
        minimal : bool
            ``False`` takes the realisation as it is (invariant zeros, decoupling zeros included):
            for a model already reduced with a chosen tolerance, whose poles and zeros must come
            from the same state dimension.
        """
        g = self.minimal() if minimal else self
        n, m, p = g.n_states, g.n_inputs, g.n_outputs
        if n == 0:
            return np.zeros(0, dtype=complex)
        if m == p:
            return _pencil_zeros(g.A, g.B, g.C, g.D)
        rng = np.random.default_rng(0)
        k = min(m, p)
        sets = []
        for _ in range(2):
            Wl = rng.standard_normal((k, p)) if p > k else np.eye(p)
            Wr = rng.standard_normal((m, k)) if m > k else np.eye(m)
            sets.append(_pencil_zeros(g.A, g.B @ Wr, Wl @ g.C, Wl @ g.D @ Wr))
        first, second = sets
        keep = [z for z in first if second.size and np.min(np.abs(second - z)) < 1e-6 * (1.0 + abs(z))]
        return np.array(keep, dtype=complex)

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
            ``v = j 2 pi f`` for continuous models, ``exp(j 2 pi f dt)`` for discrete ones.
        """
        v = frequency_variable(freqs_hz, self.dt)
        n = self.n_states
        if n == 0:
            return np.broadcast_to(self.D.astype(complex), (v.size, self.n_outputs, self.n_inputs)).copy()
        # Hessenberg form keeps each solve cheap and well conditioned.
        import scipy.linalg as sla

        H, Q = sla.hessenberg(self.A, calc_q=True)
        Bq = Q.T @ self.B
        Cq = self.C @ Q
        out = np.empty((v.size, self.n_outputs, self.n_inputs), dtype=complex)
        eye = np.eye(n)
        for k, vk in enumerate(v):
            out[k] = Cq @ np.linalg.solve(vk * eye - H, Bq) + self.D
        return out

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
        """
        uu = np.array(u, dtype=float)
        if uu.ndim == 1:
            uu = uu[:, None]
        if uu.ndim != 2 or uu.shape[1] != self.n_inputs:
            raise ModelError(f"input must have shape (n_samples, {self.n_inputs}); got {tuple(np.shape(u))}.")
        if not np.all(np.isfinite(uu)):
            raise ModelError("input contains NaN or inf.")
        model = self
        if self.dt is None:
            if dt is None:
                raise ModelError("a continuous model needs the sample time `dt` of the input to simulate.")
            from .discretization import c2d

            model = c2d(self, dt, method="zoh")
        elif dt is not None and not np.isclose(dt, self.dt, rtol=1e-6, atol=0):
            raise ModelError(f"the input's sample time {dt:g} s differs from the model's {self.dt:g} s.")
        x = np.zeros(self.n_states) if x0 is None else np.array(x0, dtype=float).reshape(-1)
        if x.shape != (self.n_states,):
            raise ModelError(f"`x0` must have shape ({self.n_states},); got {x.shape}.")
        y, _ = simulate_discrete(model.A, model.B, model.C, model.D, uu, x)
        return y

    # ------------------------------------------------------------ conversion
    def c2d(self, dt: float, method: str = "zoh") -> StateSpaceModel:
        """Discretise (``method`` = "zoh" or "tustin"); see :func:`stageid.models.c2d`."""
        from .discretization import c2d

        return c2d(self, dt, method)

    def d2c(self, method: str = "zoh") -> StateSpaceModel:
        """Continuous equivalent; see :func:`stageid.models.d2c`."""
        from .discretization import d2c

        return d2c(self, method)

    def minimal(self, tol: float | None = None) -> StateSpaceModel:
        """Remove uncontrollable and unobservable states; see :func:`stageid.models.minimal_realization`."""
        from .minimal import minimal_realization

        return minimal_realization(self, tol)

    def to_transfer(self) -> Any:
        """Return the equivalent :class:`~stageid.models.TransferMatrix` (minimal per entry)."""
        from .transfer import TransferMatrix

        return TransferMatrix.from_statespace(self)

    def to_control(self) -> Any:
        """Return a ``control.StateSpace`` with the same matrices, sample time and labels."""
        import control

        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            0 if self.dt is None else self.dt,
            inputs=list(self.inputs),
            outputs=list(self.outputs),
        )

    @classmethod
    def from_control(cls, sys: Any) -> StateSpaceModel:
        """Build from a python-control ``StateSpace`` (or anything ``control.ss`` accepts)."""
        import control

        if not isinstance(sys, control.StateSpace):
            sys = control.ss(sys)
        dt = _dt_from_control(sys.dt)
        return cls(
            np.asarray(sys.A),
            np.asarray(sys.B),
            np.asarray(sys.C),
            np.asarray(sys.D),
            dt,
            tuple(sys.input_labels),
            tuple(sys.output_labels),
        )

    def to_dict(self) -> dict[str, Any]:
        """The ``stageid.lti/1`` dictionary."""
        from .serialization import lti_to_dict

        return lti_to_dict(self)

    def to_json(self) -> str:
        """The ``stageid.lti/1`` text (byte-stable: ``from_json(s).to_json() == s``)."""
        from .serialization import dumps

        return dumps(self.to_dict())


def _count(names: Sequence[str] | None, D: object, other: object, axis: int) -> int:
    if names is not None and not isinstance(names, str) and len(names) > 0:
        return len(names)
    D_arr = np.asarray(D, dtype=float) if not isinstance(D, str) else np.zeros((0, 0))
    if D_arr.ndim == 2:
        return int(D_arr.shape[axis])
    try:
        O_arr = np.asarray(other, dtype=float)
    except (TypeError, ValueError):
        return 0
    return int(O_arr.shape[axis]) if O_arr.ndim == 2 else 0


def _pencil_zeros(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    n = A.shape[0]
    M = np.block([[A, B], [C, D]])
    N = np.zeros_like(M)
    N[:n, :n] = np.eye(n)
    import scipy.linalg as sla

    vals = sla.eigvals(M, N)
    finite = vals[np.isfinite(vals)]
    return finite[np.abs(finite) < 1e12]


def _dt_from_control(dt: Any) -> float | None:
    if dt is None or dt is True:
        raise ModelError("the python-control system has an unspecified sample time; give it a numeric dt.")
    return None if dt == 0 else float(dt)
