"""A two-mode stage (20 Hz and 120 Hz) and noisy records of it, for the residual-test tests."""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from stageid.data import Experiment
from stageid.models import StateSpaceModel

DT = 0.001


def modes(which=(0, 1)) -> StateSpaceModel:
    """The true plant (both modes) or a model missing modes (``which=(0,)``), discrete at DT."""
    table = [(20.0, 0.05, 1.0), (120.0, 0.03, 0.3)]
    n = 2 * len(which)
    A, B, C = np.zeros((n, n)), np.zeros((n, 1)), np.zeros((1, n))
    for i, m in enumerate(which):
        f, zeta, gain = table[m]
        w = 2 * np.pi * f
        A[2 * i, 2 * i + 1], A[2 * i + 1, 2 * i], A[2 * i + 1, 2 * i + 1] = 1.0, -w * w, -2 * zeta * w
        B[2 * i + 1, 0], C[0, 2 * i] = gain * w * w, 1.0
    return StateSpaceModel(A, B, C, np.zeros((1, 1)), dt=None, inputs=("u",), outputs=("y",)).c2d(DT)


def record(seed: int, n: int = 4000, noise: float = 0.1) -> Experiment:
    """Low-pass random input (AR(1), pole 0.9) through the true plant, white noise of ``noise`` x std(y)."""
    rng = np.random.default_rng(seed)
    u = lfilter([1.0], [1.0, -0.9], rng.standard_normal(n))[:, None]
    y = modes().simulate(u)
    y = y + noise * np.std(y) * rng.standard_normal(y.shape)
    return Experiment(u=u, y=y, dt=DT, input_names=("u",), output_names=("y",), name=f"seed{seed}")
