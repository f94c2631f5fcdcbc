"""Conversions between continuous and discrete time: ZOH and Tustin, both directions."""

from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

import numpy as np

from .._errors import ModelError
from .statespace import StateSpaceModel

__all__ = ["c2d", "d2c"]

_METHODS = ("zoh", "tustin")
M = TypeVar("M")


def _check_method(method: str) -> str:
    if method not in _METHODS:
        raise ModelError(f"`method` must be one of {', '.join(_METHODS)}; got {method!r}.")
    return method


def c2d(model: M, dt: float, method: str = "zoh") -> M:
    """Discretise a continuous model.

    Parameters
    ----------
    model : StateSpaceModel or TransferMatrix (continuous)
    dt : float
        Sample time in seconds.
    method : {"zoh", "tustin"}
        "zoh": exact for piecewise-constant inputs, ``Ad = expm(A dt)``,
        ``Bd = int_0^dt expm(A s) ds B`` (from the exponential of the block matrix
        ``[[A, B], [0, 0]] dt``). "tustin": bilinear map ``s = 2/dt (z-1)/(z+1)``.

    Returns
    -------
    model of the same type with ``dt`` set.

    Examples
    --------
    >>> from stageid.models import StateSpaceModel, c2d
    >>> g = c2d(StateSpaceModel([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), 0.1)
    >>> round(float(g.A[0, 0]), 6)
    0.904837
    """
    _check_method(method)
    from .transfer import TransferMatrix

    if isinstance(model, TransferMatrix):
        return model.map_entries(lambda g: c2d(g, dt, method))  # type: ignore[return-value]
    if not isinstance(model, StateSpaceModel):
        raise ModelError(f"c2d expects a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")
    if model.dt is not None:
        raise ModelError(f"the model is already discrete (dt={model.dt:g} s).")
    if not (np.isfinite(dt) and dt > 0):
        raise ModelError(f"`dt` must be a positive number of seconds; got {dt!r}.")
    A, B, C, D = model.A, model.B, model.C, model.D
    n, m = B.shape
    if method == "zoh":
        block = np.zeros((n + m, n + m))
        block[:n, :n] = A * dt
        block[:n, n:] = B * dt
        import scipy.linalg as sla

        E = sla.expm(block)
        Ad, Bd, Cd, Dd = E[:n, :n], E[:n, n:], C, D
    else:
        I = np.eye(n)
        Minv = I - A * dt / 2.0
        try:
            Ad = np.linalg.solve(Minv, I + A * dt / 2.0)
            MB = np.linalg.solve(Minv, B)
        except np.linalg.LinAlgError:
            raise ModelError(
                f"Tustin discretisation is undefined: A has an eigenvalue at 2/dt = {2 / dt:g} rad/s."
            ) from None
        Bd = MB * dt
        Cd = np.linalg.solve(Minv.T, C.T).T
        Dd = D + C @ MB * dt / 2.0
    return replace(model, A=Ad, B=Bd, C=Cd, D=Dd, dt=float(dt))  # type: ignore[return-value]


def d2c(model: M, method: str = "zoh") -> M:
    """Continuous equivalent of a discrete model.

    "zoh" inverts the zero-order hold by the principal matrix logarithm of
    ``[[Ad, Bd], [0, I]]``; it raises :class:`ModelError` when no real logarithm exists
    (an eigenvalue of ``Ad`` on the closed negative real axis, e.g. a pole at z = -0.5 or 0).
    "tustin" inverts the bilinear map (undefined for a pole at z = -1).

    Examples
    --------
    >>> from stageid.models import StateSpaceModel, c2d, d2c
    >>> g = StateSpaceModel([[-3.0]], [[2.0]], [[1.0]], [[0.0]])
    >>> round(float(d2c(c2d(g, 0.01)).A[0, 0]), 9)
    -3.0
    """
    _check_method(method)
    from .transfer import TransferMatrix

    if isinstance(model, TransferMatrix):
        return model.map_entries(lambda g: d2c(g, method))  # type: ignore[return-value]
    if not isinstance(model, StateSpaceModel):
        raise ModelError(f"d2c expects a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")
    if model.dt is None:
        raise ModelError("the model is already continuous.")
    dt = model.dt
    A, B, C, D = model.A, model.B, model.C, model.D
    n, m = B.shape
    if n == 0:
        return replace(model, dt=None)  # type: ignore[return-value]
    eig = np.linalg.eigvals(A)
    if method == "zoh":
        bad = eig[(np.abs(eig.imag) <= 1e-12 * np.maximum(1.0, np.abs(eig))) & (eig.real <= 0)]
        if bad.size:
            raise ModelError(
                f"no real matrix logarithm exists: the discrete model has a pole at z = {bad[0].real:.6g} "
                "on the closed negative real axis, so it has no continuous ZOH equivalent."
            )
        block = np.zeros((n + m, n + m))
        block[:n, :n] = A
        block[:n, n:] = B
        block[n:, n:] = np.eye(m)
        import scipy.linalg as sla

        L = sla.logm(block) / dt
        if np.iscomplexobj(L):
            if np.max(np.abs(L.imag)) > 1e-8 * max(1.0, np.max(np.abs(L.real))):
                raise ModelError("no real matrix logarithm exists for this discrete model (complex logm).")
            L = L.real
        Ac, Bc, Cc, Dc = L[:n, :n], L[:n, n:], C, D
    else:
        I = np.eye(n)
        P = A + I
        if np.min(np.abs(eig + 1.0)) < 1e-12:
            raise ModelError("the inverse Tustin map is undefined: the model has a pole at z = -1.")
        Pinv_B = np.linalg.solve(P, B)
        Ac = (2.0 / dt) * np.linalg.solve(P.T, (A - I).T).T
        Bc = 2.0 * Pinv_B / dt
        Cc = 2.0 * np.linalg.solve(P.T, C.T).T
        Dc = D - C @ Pinv_B
    return replace(model, A=Ac, B=Bc, C=Cc, D=Dc, dt=None)  # type: ignore[return-value]
