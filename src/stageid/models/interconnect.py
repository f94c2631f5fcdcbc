"""Interconnections of state-space models: series and the standard feedback loop."""

from __future__ import annotations

import numpy as np

from .._errors import ModelError
from .lti import StateSpaceModel

__all__ = ["series", "feedback"]


def _same_time_base(a: StateSpaceModel, b: StateSpaceModel) -> None:
    if (a.dt is None) != (b.dt is None) or (a.dt is not None and not np.isclose(a.dt, b.dt, rtol=1e-9)):
        raise ModelError(f"models must share one time base; got dt={a.dt} and dt={b.dt}.")


def series(first: StateSpaceModel, second: StateSpaceModel) -> StateSpaceModel:
    """``second`` driven by ``first``: y = second(first(u)).

    Raises ModelError unless ``first.n_outputs == second.n_inputs`` and the sample times agree.
    """
    _same_time_base(first, second)
    if first.n_outputs != second.n_inputs:
        raise ModelError(
            f"series needs first.n_outputs == second.n_inputs; got {first.n_outputs} and {second.n_inputs}."
        )
    n1, n2 = first.n_states, second.n_states
    A = np.block([[first.A, np.zeros((n1, n2))], [second.B @ first.C, second.A]])
    B = np.vstack([first.B, second.B @ first.D])
    C = np.hstack([second.D @ first.C, second.C])
    D = second.D @ first.D
    return StateSpaceModel(A, B, C, D, first.dt, first.inputs, second.outputs)


def feedback(plant: StateSpaceModel, controller: StateSpaceModel, noise_inputs: bool = False) -> StateSpaceModel:
    """Close the loop ``u = K (r - y_m)``, ``y = G u``, ``y_m = y + n``.

    Parameters
    ----------
    plant : StateSpaceModel G with m inputs and p outputs.
    controller : StateSpaceModel K with p inputs and m outputs, same time base.
    noise_inputs : bool
        Also take the measurement noise ``n`` (p channels) as inputs.

    Returns
    -------
    StateSpaceModel
        Inputs ``r`` (named ``r_<output>``) [then ``n_<output>``]; outputs ``y`` (the plant's
        output names) then ``u`` (the plant's input names); states ``[x_G; x_K]``.

    Raises
    ------
    ModelError
        On mismatched sizes or time bases, or an ill-posed loop (``I + D_K D_G`` singular).
    """
    _same_time_base(plant, controller)
    G, K = plant, controller
    if K.n_inputs != G.n_outputs or K.n_outputs != G.n_inputs:
        raise ModelError(
            f"the controller must have {G.n_outputs} inputs and {G.n_inputs} outputs to close the loop around this plant; "
            f"got {K.n_inputs} inputs and {K.n_outputs} outputs."
        )
    m, p = G.n_inputs, G.n_outputs
    ng, nk = G.n_states, K.n_states
    M = np.eye(m) + K.D @ G.D
    if np.linalg.cond(M) > 1e12:
        raise ModelError("the feedback loop is ill-posed: I + D_K D_G is singular (algebraic loop).")
    F = np.linalg.inv(M)
    Ux = F @ np.hstack([-K.D @ G.C, K.C])  # u = Ux x + Ur e_in, with e_in = r (- n)
    Ur = F @ K.D
    Bu = np.vstack([G.B, -K.B @ G.D])
    A = np.block([[G.A, np.zeros((ng, nk))], [-K.B @ G.C, K.A]]) + Bu @ Ux
    Br = np.vstack([np.zeros((ng, p)), K.B]) + Bu @ Ur
    Cy = np.hstack([G.C, np.zeros((p, nk))]) + G.D @ Ux
    C = np.vstack([Cy, Ux])
    Dr = np.vstack([G.D @ Ur, Ur])
    inputs = [f"r_{name}" for name in G.outputs]
    B, D = Br, Dr
    if noise_inputs:
        B = np.hstack([Br, -Br])
        D = np.hstack([Dr, -Dr])
        inputs += [f"n_{name}" for name in G.outputs]
    return StateSpaceModel(A, B, C, D, G.dt, tuple(inputs), tuple(G.outputs) + tuple(G.inputs))
