"""Conversions between continuous and discrete time: ZOH and Tustin, both directions.

The functions take either model type and call its ``c2d``/``d2c`` method; the matrix
algorithms are :func:`~stageid.models.conversions.c2d_matrices` and
:func:`~stageid.models.conversions.d2c_matrices`.
"""

from __future__ import annotations

from typing import TypeVar

from .._errors import ModelError
from .conversions import check_method
from .lti import StateSpaceModel, TransferMatrix

__all__ = ["c2d", "d2c"]

M = TypeVar("M", StateSpaceModel, TransferMatrix)


def c2d(model: M, dt: float, method: str = "zoh") -> M:
    """Discretise a continuous model.

    Parameters
    ----------
    model : StateSpaceModel or TransferMatrix (continuous)
    dt : float
        Sample time in seconds: a positive number whose sampling rate ``1/dt`` is finite.
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
    check_method(method)
    if not isinstance(model, (StateSpaceModel, TransferMatrix)):
        raise ModelError(f"c2d expects a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")
    return model.c2d(dt, method)


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
    check_method(method)
    if not isinstance(model, (StateSpaceModel, TransferMatrix)):
        raise ModelError(f"d2c expects a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")
    return model.d2c(method)
