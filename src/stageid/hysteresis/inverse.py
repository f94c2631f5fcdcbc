"""Inverses of PI and modified-PI models.

Classical PI: closed form
    The inverse of a PI model with thresholds ``0 = r_0 < r_1 < ... < r_n`` and weights
    ``w_i`` is again a PI model (Kuhnen 2003), with

    * inverse thresholds ``r'_j = sum_{i<=j} w_i (r_j - r_i)`` (the initial loading curve at
      ``r_j``),
    * inverse weights ``w'_0 = 1 / W_0``, ``w'_j = 1 / W_j - 1 / W_{j-1}`` where
      ``W_j = sum_{i<=j} w_i`` are the initial-loading slopes (all must be > 0),
    * inverse operator state ``z'_j = W_j z_j + sum_{i>j} w_i z_i`` (with ``z_0 = x``).

    The map is its own dual: applying the same formulas to the inverse gives back the model.

Modified PI: per-sample monotone inversion
    For a fixed state the output ``F(x) = y0 + sum_i w_i CP_i(x; z_i)`` of the current sample
    is piecewise linear and nondecreasing in ``x`` with slope at least
    ``s = w_0 + sum_{i>=1} min(w_i, 0) > 0``.  Each sample solves ``F(x) = y_ref`` by
    safeguarded Newton steps on the bracket ``[x_prev, x_prev + (y_ref - F(x_prev)) / s]``;
    on a piecewise-linear function the Newton step is exact once it lands on the right piece,
    so the result satisfies ``|F(x) - y_ref| <= tol`` (1e-12 of the output scale).  Drive
    limits clip ``x``, and the state follows the clipped input.
"""

from __future__ import annotations

import numpy as np

from .._errors import ModelError
from .operators import OperatorState
from .pi import ModifiedPIModel, PIModel, _as_input

__all__ = ["pi_inverse", "inverse_state", "forward_state", "invert"]


def _check_classical(model: PIModel) -> np.ndarray:
    if not isinstance(model, PIModel):
        raise ModelError(f"the closed-form inverse needs a classical PIModel; got {type(model).__name__}.")
    if model.r[0] != 0.0:
        raise ModelError(f"the closed-form inverse needs r[0] = 0 (a linear term); got r[0] = {model.r[0]:g}.")
    W = np.cumsum(model.weights)
    if np.any(W <= 0):
        j = int(np.argmax(W <= 0))
        raise ModelError(f"PI model is not invertible: initial-loading slope {j} is {W[j]:g}; every slope must be > 0.")
    return W


def inverse_state(model: PIModel, state: OperatorState | None = None) -> OperatorState:
    """Operator state of the inverse PI model matching the forward ``state`` (default the model's).

    ``z'_j = W_j z_j + sum_{i>j} w_i z_i``; the inverse's last input is the forward output
    without offset, ``z'_0``.
    """
    W = _check_classical(model)
    st = model.state if state is None else state
    z = np.array(st.z)
    w = model.weights
    tail = np.concatenate([np.cumsum((w * z)[::-1])[::-1][1:], [0.0]])  # sum_{i>j} w_i z_i
    zi = W * z + tail
    return OperatorState(float(zi[0]), zi)


def forward_state(inverse: PIModel, state: OperatorState) -> OperatorState:
    """Forward state from the state of an inverse model (the same duality formula)."""
    W = np.cumsum(inverse.weights)
    z = np.array(state.z)
    w = inverse.weights
    tail = np.concatenate([np.cumsum((w * z)[::-1])[::-1][1:], [0.0]])
    zf = W * z + tail
    return OperatorState(float(zf[0]), zf)


def pi_inverse(model: PIModel) -> PIModel:
    """The exact inverse of a classical PI model, as a PI model from output to input.

    Parameters
    ----------
    model : PIModel
        ``r[0] = 0`` and positive initial-loading slopes ``cumsum(weights)``.

    Returns
    -------
    PIModel
        Input name = the model's output name and vice versa; its state matches the model's
        state, ``input_offset`` is the model's ``output_offset`` and the other way round.

    Raises
    ------
    ModelError
        If the model is not a classical PI model or not invertible.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, pi_inverse
    >>> m = PIModel(r=[0.0, 1.0, 2.0], weights=[1.0, 0.5, 0.25])
    >>> u = np.array([0.0, 3.0, -1.0, 2.0])
    >>> x = pi_inverse(m).simulate(m.simulate(u))
    >>> bool(np.allclose(x[:, 0], u))
    True
    """
    W = _check_classical(model)
    if getattr(model, "creep", None) is not None:
        raise ModelError(
            "the closed-form inverse is rate independent; got a model with a creep term (use invert or Compensator)."
        )
    r, w = model.r, model.weights
    r_inv = np.array([np.sum(w[: j + 1] * (r[j] - r[: j + 1])) for j in range(r.size)])
    w_inv = np.empty_like(w)
    w_inv[0] = 1.0 / W[0]
    w_inv[1:] = 1.0 / W[1:] - 1.0 / W[:-1]
    return PIModel(
        r=r_inv,
        weights=w_inv,
        input_offset=model.output_offset,
        output_offset=model.input_offset,
        state=inverse_state(model),
        inputs=model.outputs,
        outputs=model.inputs,
    )


def _packed(model: ModifiedPIModel | PIModel) -> np.ndarray:
    r, rc, ra, rb = model._params()
    return np.ascontiguousarray(np.vstack([r, rc, ra, rb, model.weights]))


def _tolerance(model) -> float:
    scale = float(np.sum(np.abs(model.weights)) * (1.0 + np.max(model.r)))
    return 1e-12 * max(scale, 1e-300)


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
    (:class:`~stageid.hysteresis.creep.CreepInverse`, creep at rest at the state's input
    unless the term carries a state).

    Returns
    -------
    u : ndarray of shape (n_samples, 1)
        Inputs; ``model.simulate(u) == y`` to 1e-12 of the output scale where no limit is hit.
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
    from . import kernels

    if getattr(model, "creep", None) is not None:  # rate dependent: per-sample inverse with creep state
        from .creep import CreepInverse

        inv = CreepInverse(model, limits)
        return inv.run(y), inv.state
    smin = model.min_slope()
    if not smin > 0:
        raise ModelError(f"model is not invertible: its minimum slope w0 + sum(min(w_i, 0)) is {smin:g}; expected > 0.")
    target = np.ascontiguousarray(_as_input(y, model.outputs[0]) - model.output_offset)
    from .compensator import _check_limits

    lim = _check_limits(limits if limits is not None else model.input_limits)
    lo, hi = (
        (-np.inf, np.inf)
        if lim is None
        else (float(model.to_operator_input(float(lim[0]))), float(model.to_operator_input(float(lim[1]))))
    )
    x, zf, xf = kernels.cp_invert(
        target, _packed(model), np.array(model.state.z), float(model.state.x), lo, hi, smin, _tolerance(model)
    )
    u = model.from_operator_input(x)
    if lim is not None:  # the warp's inverse may round a clipped value a hair outside
        u = np.clip(u, float(lim[0]), float(lim[1]))
    return u[:, None], OperatorState(float(xf), zf)
