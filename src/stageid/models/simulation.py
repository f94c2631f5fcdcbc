"""Time responses of the LTI models: the work behind ``StateSpaceModel.simulate`` and
``TransferMatrix.simulate``.

A discrete state-space model runs its exact recursion (:func:`~._kernels.simulate_discrete`), a
continuous one the recursion of its zero-order-hold equivalent at the input's sample time; a
discrete transfer matrix is filtered entry by entry (its difference equations), a continuous one
goes through its state-space form.  A response that leaves the floating-point range raises
:class:`~stageid.ModelError` naming the sample (:func:`~._validate.check_response`).  The
functions take the model objects as they come (their matrices, coefficients and methods) and
import no model class, so :mod:`.lti` builds on them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ModelError
from . import conversions as cv
from ._kernels import simulate_discrete
from ._validate import check_response, check_same_dt, input_samples

__all__ = ["simulate_statespace", "simulate_transfer"]


def simulate_statespace(model: Any, u: Any, x0: Any = None, dt: float | None = None) -> np.ndarray:
    """Response of a state-space ``model`` to ``u`` from state ``x0`` (zero by default); ``dt`` the
    input's sample time (needed by a continuous model, equal to a discrete model's own)."""
    uu = input_samples(u, model.n_inputs)
    if not np.all(np.isfinite(uu)):
        raise ModelError("input contains NaN or inf.")
    run = model
    if model.dt is None:
        if dt is None:
            raise ModelError("a continuous model needs the sample time `dt` of the input to simulate.")
        run = model.c2d(dt, method="zoh")
    else:
        check_same_dt(dt, model.dt)
    x = np.zeros(model.n_states) if x0 is None else np.array(x0, dtype=float).reshape(-1)
    if x.shape != (model.n_states,):
        raise ModelError(f"`x0` must have shape ({model.n_states},); got {x.shape}.")
    with np.errstate(over="ignore", invalid="ignore"):  # divergence is reported below
        y, _ = simulate_discrete(run.A, run.B, run.C, run.D, uu, x)
    return check_response(y, model.poles(), model.dt) if not np.isfinite(y).all() else y


def simulate_transfer(model: Any, u: Any, dt: float | None = None) -> np.ndarray:
    """Response of a transfer matrix ``model`` to ``u`` from rest (``dt`` as :func:`simulate_statespace`)."""
    uu = input_samples(u, model.n_inputs)
    if model.dt is None:
        return simulate_statespace(model.to_statespace(minimal=False), uu, dt=dt)
    check_same_dt(dt, model.dt)
    y = cv.filter_entries(model.num, model.den, uu)
    if not np.isfinite(y).all():
        poles = [model.entry_poles(i, j) for i in range(model.n_outputs) for j in range(model.n_inputs)]
        return check_response(y, np.concatenate(poles), model.dt)
    return y
