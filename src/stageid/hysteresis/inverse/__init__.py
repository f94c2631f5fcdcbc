"""Inverses of PI and modified-PI models.

Classical PI: closed form (:mod:`.closed_form`, re-exported here)
    The inverse of a PI model with thresholds ``0 = r_0 < r_1 < ... < r_n`` and weights
    ``w_i`` is again a PI model (Kuhnen 2003), with

    * inverse thresholds ``r'_j = sum_{i<=j} w_i (r_j - r_i)`` (the initial loading curve at
      ``r_j``),
    * inverse weights ``w'_0 = 1 / W_0``, ``w'_j = 1 / W_j - 1 / W_{j-1}`` where
      ``W_j = sum_{i<=j} w_i`` are the initial-loading slopes (all must be > 0),
    * inverse operator state ``z'_j = W_j z_j + sum_{i>j} w_i z_i`` (with ``z_0 = x``).

    The map is its own dual: applying the same formulas to the inverse gives back the model.

Modified PI: per-sample monotone inversion (eq. 5)
    The letter writes the inverse of the modified PI model as an operator sum of the same kind
    (eq. 5) without giving its parameters; we read it as what it must be, the exact inverse of
    the forward model sample by sample.  For a fixed state the output
    ``F(x) = y0 + sum_i w_i CP_i(x; z_i)`` of the current sample is piecewise linear and
    nondecreasing in ``x`` with slope at least ``s = w_0 + sum_{i>=1} min(w_i, 0) > 0``, so
    ``F(x) = y_ref`` has exactly one root.  Each sample finds it by safeguarded Newton steps
    on the bracket ``[x_prev, x_prev + (y_ref - F(x_prev)) / s]``.  On a piecewise-linear
    function a Newton step from the piece that holds the root lands on the root itself, so the
    iteration does not stop at a tolerance: it goes on until ``|F(x) - y_ref|`` is within the
    rounding error of the computed F (:func:`~stageid.hysteresis.models.common.residual_bound`,
    about ``4 (m + 2) 2**-53 sum|w| (|x| + max r)``), one step after it first reaches the
    right piece.  The drive is the exact root to rounding (it does not depend on how the
    iteration got there: any exact solver, e.g. the exported C, agrees with it to rounding).
    Drive limits clip ``x``, and the state follows the clipped input.

This package, the inverse side of the letter (eq. 5, Fig. 9):

=========================  ================================================================
module                     what it holds
=========================  ================================================================
``__init__`` (here)        ``invert``: per-sample monotone inversion (eq. 5), re-exports
                           the closed form
:mod:`.closed_form`        the classical PI's inverse PI model (``pi_inverse``)
:mod:`.compensator`        Fig. 9 feedforward: ``Compensator`` (streaming), ``compensate``
                           (batch), ``CreepInverse``
:mod:`.preisach`           exact Preisach inverse: ``PreisachCompensator``,
                           ``preisach_feedforward``
=========================  ================================================================
"""

from __future__ import annotations

import numpy as np

from ..._errors import ModelError
from ..models.common import as_input, check_limits, limited_drive, packed, residual_bound
from ..models.operators import OperatorState
from ..models.pi import ModifiedPIModel, PIModel
from .closed_form import forward_state, inverse_state, pi_inverse
from .compensator import CreepInverse

__all__ = ["pi_inverse", "inverse_state", "forward_state", "invert"]


def invert(
    model: ModifiedPIModel | PIModel, y: object, limits: tuple[float, float] | None = None
) -> tuple[np.ndarray, OperatorState]:
    """Per-sample monotone inversion: inputs that make ``model`` output ``y``.

    Parameters
    ----------
    model : ModifiedPIModel or PIModel
        With ``model.min_slope() > 0``.
    y : array_like of shape (n_samples, 1) or (n_samples,)
        Desired outputs.
    limits : (float, float), optional
        Drive limits; default ``model.input_limits`` (unlimited if None).

    A model with a ``creep`` term is inverted sample by sample with its creep state
    (:class:`~stageid.hysteresis.inverse.compensator.CreepInverse`, creep at rest at the state's input
    unless the term carries a state).

    Returns
    -------
    u : ndarray of shape (n_samples, 1)
        Inputs; ``model.simulate(u) == y`` to rounding where no limit is hit (the exact root
        of each sample's equation, see the module notes).
    state : OperatorState
        The model's final state.

    Raises
    ------
    ModelError
        If the model is not monotone (``min_slope() <= 0``) or ``y`` is malformed.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import ModifiedPIModel, invert
    >>> m = ModifiedPIModel(r=[0.0, 1.0], rc=[0.0, 0.5], ra=[0.0, 2.0], rb=[0.0, 1.0],
    ...                     weights=[1.0, 1.0])
    >>> yd = np.array([0.0, 5.0, 1.0, -4.0])
    >>> u, _ = invert(m, yd)
    >>> bool(np.allclose(m.simulate(u)[:, 0], yd))
    True
    """
    from .. import kernels  # numba: imported on first use

    if getattr(model, "creep", None) is not None:  # rate dependent: per-sample inverse with creep state
        inv = CreepInverse(model, limits)
        return inv.run(y), inv.state
    smin = model.min_slope()
    if not smin > 0:
        raise ModelError(f"model is not invertible: its minimum slope w0 + sum(min(w_i, 0)) is {smin:g}; expected > 0.")
    target = np.ascontiguousarray(as_input(y, model.outputs[0]) - model.output_offset)
    lim = check_limits(limits if limits is not None else model.input_limits)
    lo, hi = (
        (-np.inf, np.inf)
        if lim is None
        else (float(model.to_operator_input(float(lim[0]))), float(model.to_operator_input(float(lim[1]))))
    )
    x, zf, xf = kernels.cp_invert(
        target, packed(model), np.array(model.state.z), float(model.state.x), lo, hi, smin, *residual_bound(model)
    )
    return limited_drive(model, x, lim, (lo, hi))[:, None], OperatorState(float(xf), zf)
