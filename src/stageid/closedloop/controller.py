"""The known controller of the loop: discrete at the data's sample time, and checked before a fit.

Eq. 18 divides by ``M (I - T)``; a controller singular at some frequency makes it singular there
whatever ``T`` is, so :func:`check_controller` refuses it before any fit, on the grid of
:func:`check_grid` (from 0 Hz: the controller is known everywhere).  :func:`resolved_grid` is
that grid from the records' frequency resolution up, where the identified ``T`` is known too.
"""

from __future__ import annotations

import numpy as np

from .._errors import IdentificationError, ModelError
from ..data.sampling import PERIOD_RTOL, same_period, seconds
from ..models import StateSpaceModel, TransferMatrix

__all__ = [
    "as_statespace",
    "as_discrete_controller",
    "discrete_controllers",
    "check_grid",
    "resolved_grid",
    "check_controller",
]


def as_statespace(model: StateSpaceModel | TransferMatrix) -> StateSpaceModel:
    """``model`` as a StateSpaceModel (a TransferMatrix realised without minimising), else ModelError."""
    if isinstance(model, TransferMatrix):
        return model.to_statespace(minimal=False)
    if isinstance(model, StateSpaceModel):
        return model
    raise ModelError(f"expected a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")


def as_discrete_controller(
    controller: StateSpaceModel | TransferMatrix, dt: float, method: str = "tustin"
) -> StateSpaceModel:
    """The controller as a discrete state-space model at ``dt``.

    A continuous controller is discretised with ``method`` ("tustin" by default, the
    usual way a continuous design is implemented digitally); a discrete one must
    already have sample time ``dt``.

    Raises
    ------
    ModelError
        When a discrete controller's sample time differs from ``dt``.
    """
    K = as_statespace(controller)
    if K.dt is None:
        return K.c2d(dt, method)
    if not same_period(K.dt, dt):
        raise ModelError(
            f"the controller's sample time {seconds(K.dt)} s differs from the data's {seconds(dt)} s "
            f"(tolerance {PERIOD_RTOL:g} relative)."
        )
    return K


def discrete_controllers(
    controller: StateSpaceModel | TransferMatrix,
    reference_filter: StateSpaceModel | TransferMatrix | None,
    dt: float,
    method: str,
    p: int,
) -> tuple[StateSpaceModel, StateSpaceModel | None]:
    """``(M, M_r)`` discrete at ``dt`` (``M_r`` None for a one-degree-of-freedom law).

    Raises
    ------
    IdentificationError
        When a sample time differs from ``dt`` or ``M`` does not map ``p`` errors to ``p`` inputs.
    """
    try:
        M = as_discrete_controller(controller, dt, method)
        Mr = None if reference_filter is None else as_discrete_controller(reference_filter, dt, method)
    except ModelError as exc:
        raise IdentificationError(str(exc)) from None
    if M.n_inputs != p or M.n_outputs != p:
        raise IdentificationError(
            f"the controller must have {p} inputs (tracking errors) and {p} outputs (plant inputs) for {p} outputs; "
            f"got {M.n_inputs} inputs and {M.n_outputs} outputs."
        )
    return M, Mr


def check_grid(f_low: float, dt: float) -> np.ndarray:
    """Where eq. 18 is checked: 0 Hz, then 400 log-spaced lines from ``min(f_low / 10, 1 Hz)`` to 0.95 Nyquist."""
    return np.concatenate([[0.0], np.geomspace(min(f_low / 10, 1.0), 0.95 * (0.5 / dt), 400)])


def resolved_grid(f_low: float, dt: float, f_resolution: float) -> np.ndarray:
    """:func:`check_grid` without the lines below ``f_resolution`` (the records' ``1 / duration``).

    The controller is known at every frequency, 0 Hz included; the identified ``T`` only where the
    records resolve it.  Below that, ``T`` is the pairs' extrapolation: with a lag the loop gain at
    DC is ~1e4, so ``M (I - T)`` there hangs on ``T(0)`` to ~1e-4, which a 1-2 s record does not
    fix, and a pair free at DC can make eq. 18 look singular where the true loop is not.
    """
    grid = check_grid(f_low, dt)
    return grid[grid >= f_resolution]


def check_controller(controller: StateSpaceModel, freqs_hz: np.ndarray) -> None:
    """IdentificationError when the controller is singular at some frequency of ``freqs_hz``.

    A singular controller makes eq. 18 singular there whatever ``T`` is, so this is checked
    before any fit.  Frequencies where the controller has a pole (infinite gain) are skipped.
    """
    with np.errstate(all="ignore"):
        K = controller.frequency_response(freqs_hz)
    ok = np.all(np.isfinite(K), axis=(1, 2))
    sv = np.linalg.svd(K[ok], compute_uv=False)
    bad = np.flatnonzero(sv[:, -1] <= 1e-6 * sv[:, 0].max())
    if bad.size:
        k = int(bad[0])
        raise IdentificationError(
            f"the plant deduction G = T (M - M T)^-1 is singular at {freqs_hz[ok][k]:.6g} Hz: the controller itself is singular "
            f"there (smallest singular value {sv[k, -1]:.3g}, {sv[k, -1] / sv[:, 0].max():.2g} of its peak gain)."
        )
