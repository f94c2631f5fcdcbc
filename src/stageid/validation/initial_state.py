"""The initial state of an LTI model that best explains a record (MATLAB ``compare(..., 'e')``).

A record seldom starts with the stage at rest.  Simulating from ``x0 = 0`` then carries a start-up
transient that is the model's free response, not its error.  The response is linear in the
initial state::

    y(k) = y_rest(k) + C A^k x0          (the discrete model; a continuous one under a zero-order hold)

so ``x0`` is the least-squares solution of ``O x0 = y - y_rest`` with ``O`` the stacked free
responses ``C A^k`` (the extended observability matrix of the record's length).  Directions the
record does not observe get no weight (minimum-norm solution).
"""

from __future__ import annotations

import numpy as np

from .._errors import ModelError

__all__ = ["estimate_initial_state", "simulate_from_estimated_state"]


def _discrete_statespace(model, dt: float | None):
    """``model`` as a discrete :class:`~stageid.models.StateSpaceModel` at the record's sample time."""
    to_ss = getattr(model, "to_statespace", None)
    ss = to_ss(minimal=False) if to_ss is not None else model
    if not hasattr(ss, "A"):
        raise ModelError(f"an initial state is estimated for LTI models; got {type(model).__name__}.")
    if ss.dt is None:
        if dt is None:
            raise ModelError("a continuous model needs the record's sample time `dt` to estimate its initial state.")
        ss = ss.c2d(dt, method="zoh")
    return ss


def estimate_initial_state(model, u: np.ndarray, y: np.ndarray, dt: float | None = None) -> np.ndarray:
    """Least-squares initial state of ``model`` on one record.

    Parameters
    ----------
    model : StateSpaceModel or TransferMatrix
        Discrete, or continuous (then discretised with a zero-order hold at ``dt``).
    u : array_like of shape (n_samples, n_inputs)
    y : array_like of shape (n_samples, n_outputs)
        The measured output.
    dt : float, optional
        Sample time of the record (needed for a continuous model).

    Returns
    -------
    ndarray of shape (n_states,)
        The state of the discrete model (a continuous model's zero-order-hold discretisation,
        whose state is the continuous state) minimising ``sum |(y - y_model) / s|^2``, ``s``
        per output the standard deviation of its error from rest.

    Raises
    ------
    ModelError
        A model that is not LTI, or a continuous model without ``dt``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.models import StateSpaceModel
    >>> from stageid.validation.initial_state import estimate_initial_state
    >>> g = StateSpaceModel([[0.9]], [[1.0]], [[1.0]], [[0.0]], dt=0.01)
    >>> u = np.zeros((50, 1))
    >>> y = g.simulate(u, x0=[2.0])
    >>> np.round(estimate_initial_state(g, u, y), 6)
    array([2.])
    """
    ss = _discrete_statespace(model, dt)
    if ss.n_states == 0:  # a static gain has no state to estimate
        return np.zeros(0)
    uu = np.asarray(u, dtype=float).reshape(len(u), -1)
    yy = np.asarray(y, dtype=float).reshape(len(y), -1)
    error = yy - ss.simulate(uu)  # the error from rest: noise plus the start-up transient
    # each output weighed by 1 / its error's spread (about the noise's, as maximum likelihood would):
    # um and urad channels count alike, and a noisy output does not pull the state
    spread = np.std(error, axis=0)
    scale = 1.0 / np.where(spread > 0, spread, 1.0)
    n = _free_response_length(ss, uu.shape[0])
    zero = np.zeros_like(uu[:n])
    # column i: the free response C A^k e_i, scaled and flattened like the error
    free = np.column_stack([(ss.simulate(zero, x0=e) * scale).reshape(-1) for e in np.eye(ss.n_states)])
    x0, *_ = np.linalg.lstsq(free, (error[:n] * scale).reshape(-1), rcond=None)
    return x0


def _free_response_length(ss, n_samples: int) -> int:
    """Samples over which the free response of a stable model is above 1e-12 of its start: the
    rows after it are zeros of ``O`` and would only cost memory on a long record."""
    radius = float(np.max(np.abs(ss.poles()))) if ss.n_states else 0.0
    if radius >= 1.0:
        return n_samples
    decay = int(np.ceil(np.log(1e-12) / np.log(max(radius, 1e-12))))
    return min(n_samples, max(decay + ss.n_states, 10 * ss.n_states, 1))


def simulate_from_estimated_state(model, u: np.ndarray, y: np.ndarray, dt: float | None = None) -> np.ndarray:
    """The response of ``model`` to ``u`` from :func:`estimate_initial_state` on ``(u, y)``.

    Returns
    -------
    ndarray of shape (n_samples, n_outputs)
    """
    ss = _discrete_statespace(model, dt)
    return ss.simulate(np.asarray(u, dtype=float), x0=estimate_initial_state(ss, u, y))
