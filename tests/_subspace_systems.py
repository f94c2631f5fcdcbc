"""Shared test systems for the subspace tests: random lightly damped MIMO stages and records."""

from __future__ import annotations

import numpy as np

from stageid.data import Experiment
from stageid.models import StateSpaceModel


def random_stage(seed: int, m: int = 2, q: int = 2, modes: int = 4, dt: float = 0.002) -> StateSpaceModel:
    """A random stage: ``modes`` resonances at 8-90 Hz with damping 0.5-3 %, discretised by ZOH."""
    rng = np.random.default_rng(seed)
    fs = np.sort(rng.uniform(8, 90, modes))
    zs = rng.uniform(0.005, 0.03, modes)
    A = np.zeros((2 * modes, 2 * modes))
    B = np.zeros((2 * modes, m))
    C = np.zeros((q, 2 * modes))
    for i, (f, z) in enumerate(zip(fs, zs)):
        w = 2 * np.pi * f
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[0, 1], [-w * w, -2 * z * w]]
        B[2 * i + 1] = rng.standard_normal(m) * w * w
        C[:, 2 * i] = rng.standard_normal(q) / modes
    return StateSpaceModel(A, B, C, np.zeros((q, m)), None).c2d(dt)


def band_limited(n: int, m: int, dt: float, seed: int, f_low: float = 1.0, f_high: float = 100.0) -> np.ndarray:
    """Independent Gaussian inputs with no FFT energy outside [f_low, f_high], unit std."""
    rng = np.random.default_rng(seed)
    f = np.fft.rfftfreq(n, dt)
    spec = np.fft.rfft(rng.standard_normal((n, m)), axis=0)
    spec[(f < f_low) | (f > f_high)] = 0.0
    u = np.fft.irfft(spec, n, axis=0)
    return u / u.std(axis=0)


def record(g: StateSpaceModel, u: np.ndarray, noise: float, seed: int, names: bool = True) -> Experiment:
    """Simulate ``g`` and add white output noise of ``noise`` times each output's std."""
    y = g.simulate(u)
    y = y + noise * y.std(axis=0) * np.random.default_rng(seed + 1000).standard_normal(y.shape)
    if names:
        return Experiment(u, y, g.dt, g.inputs, g.outputs)
    return Experiment(u, y, g.dt)


def column_errors(
    estimated: StateSpaceModel, true: StateSpaceModel, f_low: float = 1.0, f_high: float = 100.0, n: int = 1000
) -> tuple[float, float]:
    """(largest diagonal error, largest coupling error), each relative to its input column's peak gain."""
    f = np.linspace(f_low, f_high, n)
    Gt = true.frequency_response(f)
    Ge = estimated.frequency_response(f)
    e = np.abs(Ge - Gt).max(axis=0) / np.abs(Gt).max(axis=(0, 1))[None, :]
    k = min(e.shape)
    diag = np.zeros_like(e, dtype=bool)
    diag[np.arange(k), np.arange(k)] = True
    return float(e[diag].max()), float(e[~diag].max()) if (~diag).any() else 0.0
