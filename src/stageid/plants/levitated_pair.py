"""A two-axis levitated stage: an unstable 2x2 plant under decentralised filtered PD control.

Each axis is a mass on a magnetic negative spring, ``x'' = a^2 x + b u``, with poles at
``+-a`` (``a`` = 31.4 and 50 rad/s); the two actuators couple through ``B_c``.  The plant is
sampled by zero-order hold at 1 kHz.  Each axis is stabilised by a PD with a first-order
filter on the derivative, ``k_p + k_d s / (tau s + 1)`` (Tustin), tuned for a 20 Hz closed
loop.  :func:`record` runs the loop with options a real controller adds and an identification
route that is not told the controller must survive: saturation, a delay in the feedback,
measurement and input noise.  This is the ground truth of the tests and benchmarks of the
routes that do not use the controller (:mod:`stageid.closedloop.direct`).
"""

from __future__ import annotations

import numpy as np

from ..models import StateSpaceModel

__all__ = ["model", "controller", "record", "UNSTABLE_POLES", "DT"]

DT = 1e-3
UNSTABLE_POLES = (2 * np.pi * 5.0, 50.0)  # rad/s, one per axis
_B_COUPLING = np.array([[1.0, 0.2], [0.15, 1.0]])
_CLOSED_LOOP_RAD_S = 2 * np.pi * 20.0


def model(dt: float = DT) -> StateSpaceModel:
    """The plant sampled at ``dt`` (zero-order hold): inputs ``u1, u2``, outputs ``x1, x2``, 4 states."""
    A = np.zeros((4, 4))
    B = np.zeros((4, 2))
    for k, a in enumerate(UNSTABLE_POLES):
        A[2 * k, 2 * k + 1] = 1.0
        A[2 * k + 1, 2 * k] = a * a
        B[2 * k + 1] = _B_COUPLING[k]
    C = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    g = StateSpaceModel(A, B, C, np.zeros((2, 2)), None, ("u1", "u2"), ("x1", "x2"))
    return g.c2d(dt, "zoh")


def controller(dt: float = DT, gain: float = 1.0) -> StateSpaceModel:
    """Decentralised filtered PD per axis (Tustin), errors ``e1, e2`` to ``u1, u2``; ``gain`` scales it."""
    w = _CLOSED_LOOP_RAD_S
    tau = 1.0 / (2 * np.pi * 200.0)
    A, B, C, D = [], [], [], []
    for a in UNSTABLE_POLES:
        kp, kd = gain * (w * w + a * a), gain * 2 * 0.7 * w
        # kp + kd s / (tau s + 1) = (kp + kd / tau) - (kd / tau^2) / (s + 1 / tau)
        A.append(-1.0 / tau)
        B.append(1.0)
        C.append(-kd / tau**2)
        D.append(kp + kd / tau)
    k = StateSpaceModel(np.diag(A), np.diag(B), np.diag(C), np.diag(D), None, ("e1", "e2"), ("u1", "u2"))
    return k.c2d(dt, "tustin")


def record(
    n_samples: int = 6000,
    seed: int = 0,
    noise: float = 0.02,
    saturation: float | None = None,
    delay: int = 0,
    input_noise: float = 0.0,
    reference_axes: tuple[int, ...] = (0, 1),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One closed-loop record: references ``r``, plant inputs ``u`` (logged) and measured ``y``.

    ``noise`` is the white measurement noise's std relative to each output's std (it is fed
    back), ``input_noise`` a white input disturbance relative to each input's std; both are
    set from a noise-free run of the same references.  ``saturation`` is a fraction of the
    noise-free run's largest ``|u|``.  The references are band-limited noise on the axes in
    ``reference_axes`` (others zero).

    Returns ``(r, u, y)``, each of shape (n_samples, 2).
    """
    from scipy.signal import butter, lfilter

    from ..closedloop.feedback_simulation import simulate_feedback

    rng = np.random.default_rng(seed)
    b, a = butter(2, 2 * 60.0 * DT)  # references up to 60 Hz
    r = np.zeros((n_samples, 2))
    for k in reference_axes:
        r[:, k] = lfilter(b, a, rng.standard_normal(n_samples)) * 1e-3
    G, M = model(), controller()
    u0, y0 = simulate_feedback(G, M, r, delay=delay)
    v = noise * y0.std(axis=0) * rng.standard_normal((n_samples, 2))
    w = input_noise * u0.std(axis=0) * rng.standard_normal((n_samples, 2))
    lim = None if saturation is None else saturation * float(np.abs(u0).max())
    u, y = simulate_feedback(G, M, r, measurement_noise=v, input_noise=w, saturation=lim, delay=delay)
    return r, u, y
