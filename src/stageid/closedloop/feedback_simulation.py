"""Sampled feedback loops with what real controllers add: input saturation and a delay in the feedback.

:func:`simulate_feedback` runs ``u = sat(M (r - y_m(t - delay)))``, ``y = G (u + w)``,
``y_m = y + v`` sample by sample, so the loop may be nonlinear (saturation) where
:func:`~stageid.closedloop.simulate_closed_loop` is linear.  It is the test bench of the
identification routes that are not told the controller.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError, ModelError
from ..models import StateSpaceModel

__all__ = ["simulate_feedback"]


def _check(plant: StateSpaceModel, controller: StateSpaceModel, r: np.ndarray, delay: int) -> None:
    if plant.dt is None or controller.dt is None or abs(plant.dt - controller.dt) > 1e-12 * plant.dt:
        raise ModelError("plant and controller must be discrete at the same sample time.")
    p, m = plant.n_outputs, plant.n_inputs
    if controller.n_inputs != p or controller.n_outputs != m:
        raise ModelError(
            f"the controller must map {p} errors to {m} plant inputs; got {controller.n_inputs} inputs "
            f"and {controller.n_outputs} outputs."
        )
    if delay == 0 and np.any(plant.D) and np.any(controller.D):
        raise ModelError("a loop without delay needs a strictly proper plant or controller; both feed through.")
    if r.ndim != 2 or r.shape[1] != p:
        raise DataError(f"`r` must have shape (n_samples, {p}); got {r.shape}.")


def simulate_feedback(
    plant: StateSpaceModel,
    controller: StateSpaceModel,
    r: np.ndarray,
    *,
    measurement_noise: np.ndarray | None = None,
    input_noise: np.ndarray | None = None,
    saturation: float | None = None,
    delay: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Run the loop ``u = sat(M (r - y_m(t - delay)))``, ``y = G (u + w)``, ``y_m = y + v``.

    Parameters
    ----------
    plant : StateSpaceModel
        Discrete ``G``, m inputs, p outputs (may be unstable: the loop must stabilise it).
    controller : StateSpaceModel
        Discrete ``M``, p tracking errors to m plant inputs, same sample time.
    r : ndarray of shape (n_samples, p)
        References.
    measurement_noise, input_noise : ndarray of shape (n_samples, p) / (n_samples, m), optional
        ``v`` added to the measured outputs (and fed back) and ``w`` added to the plant input
        after the controller (a disturbance the recorded ``u`` does not contain).
    saturation : float, optional
        ``|u| <= saturation`` per channel (the controller's state is not told: no anti-windup).
    delay : int
        Samples between the measurement and the controller's use of it.

    Returns
    -------
    u : ndarray of shape (n_samples, m)
        The controller's (saturated) outputs, as a recorder would log them.
    y : ndarray of shape (n_samples, p)
        The measured outputs ``y_m``.

    Raises
    ------
    ModelError
        Sizes or sample times that do not fit, an algebraic loop, or a loop that diverges.
    DataError
        References or noise of the wrong shape.
    """
    r = np.asarray(r, dtype=float)
    _check(plant, controller, r, int(delay))
    n_s, p, m = r.shape[0], plant.n_outputs, plant.n_inputs
    v = np.zeros((n_s, p)) if measurement_noise is None else np.asarray(measurement_noise, float).reshape(n_s, p)
    w = np.zeros((n_s, m)) if input_noise is None else np.asarray(input_noise, float).reshape(n_s, m)
    A, B, C, D = plant.A, plant.B, plant.C, plant.D
    Ak, Bk, Ck, Dk = controller.A, controller.B, controller.C, controller.D
    x, xk = np.zeros(plant.n_states), np.zeros(controller.n_states)
    u_log, y_log = np.empty((n_s, m)), np.empty((n_s, p))
    lim = np.inf if saturation is None else float(saturation)
    plant_first = delay == 0 and not np.any(D)  # y(t) does not need u(t): measure, then act
    for t in range(n_s):
        if plant_first:
            y_log[t] = C @ x + v[t]
            e = r[t] - y_log[t]
            u = np.clip(Ck @ xk + Dk @ e, -lim, lim)
        else:  # act on older measurements (or a strictly proper controller), then measure
            e_old = r[t] - y_log[t - delay] if t >= delay else r[t]
            u = np.clip(Ck @ xk + (Dk @ e_old if delay else 0.0), -lim, lim)
            y_log[t] = C @ x + D @ (u + w[t]) + v[t]
            e = e_old if delay else r[t] - y_log[t]
        xk = Ak @ xk + Bk @ e
        x = A @ x + B @ (u + w[t])
        u_log[t] = u
        if not np.all(np.isfinite(x)) or np.abs(x).max() > 1e150:
            raise ModelError(f"the loop diverged at sample {t}: the controller does not stabilise the plant.")
    return u_log, y_log
