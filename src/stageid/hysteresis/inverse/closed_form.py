"""The closed-form inverse of a classical PI model (eq. 5 for plays).

The inverse of a PI model with thresholds ``0 = r_0 < r_1 < ... < r_n`` and weights
``w_i`` is again a PI model (Kuhnen 2003), with

* inverse thresholds ``r'_j = sum_{i<=j} w_i (r_j - r_i)`` (the initial loading curve at
  ``r_j``),
* inverse weights ``w'_0 = 1 / W_0``, ``w'_j = 1 / W_j - 1 / W_{j-1}`` where
  ``W_j = sum_{i<=j} w_i`` are the initial-loading slopes (all must be > 0),
* inverse operator state ``z'_j = W_j z_j + sum_{i>j} w_i z_i`` (with ``z_0 = x``).

The map is its own dual: applying the same formulas to the inverse gives back the model.
"""

from __future__ import annotations

import numpy as np

from ..._errors import ModelError
from ..models.operators import OperatorState
from ..models.pi import PIModel

__all__ = ["pi_inverse", "inverse_state", "forward_state"]


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
