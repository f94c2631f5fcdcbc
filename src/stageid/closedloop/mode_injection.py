"""Starts for an output-error fit that has missed a lightly damped mode: the mode added where the
residual still follows the input.

An output-error optimisation from a linear start can settle with one lightly damped mode of the
loop left out: the loss is then a local minimum (measured on 3x3 loops of Shakir & Kim's class at
1.23-1.26x the noise floor, the missing coupling mode 1.9 % off at its frequency), and neither more
iterations nor a higher order started the same way leave it.  The residual ``e = y - B/F r`` still
carries the missing mode's response to the input, so the peak of ``|S_er|^2 / S_rr`` (the residual
power the input explains, per line) says where it sits.  Multiplying both ``B`` and ``F`` by a
second-order section with poles there gives the same model (a cancelling pole-zero pair) two
orders up, from which the optimisation can pull the pole away from its zero.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.signal as ss

from .polynomial import PolynomialModel

__all__ = ["explained_residual_peaks", "with_modes", "INJECTED_DAMPING", "SEGMENT"]

#: damping ratio of an added mode: the light end of a stage's couplings (0.3-5 %); a lightly
#: damped start the optimisation can widen (measured: 0.3 % escaped where 3 % did not)
INJECTED_DAMPING = 0.003
#: samples per Welch segment of the residual's cross-spectrum with the input
SEGMENT = 2048


def explained_residual_peaks(
    model: PolynomialModel, segs: list[tuple[np.ndarray, np.ndarray]], n_peaks: int
) -> list[float]:
    """Up to ``n_peaks`` frequencies (rad/sample, strongest first, at least three lines apart) at
    which the residual of ``model`` on the records ``segs = [(u, y), ...]`` is explained by the input:
    the peaks of ``|S_eu|^2 / S_uu`` summed over the records."""
    n_seg = min(SEGMENT, min(u.size for u, _ in segs))
    explained = 0.0
    for u, y in segs:
        e = y - model.simulate(u)
        w, s_eu = ss.csd(u, e, nperseg=n_seg)
        _, s_uu = ss.welch(u, nperseg=n_seg)
        explained = explained + np.abs(s_eu) ** 2 / np.maximum(s_uu, np.finfo(float).tiny)
    explained = np.asarray(explained, dtype=float)
    explained[0] = 0.0  # the DC line is the level's, not a mode's
    peaks: list[int] = []
    for k in np.argsort(explained)[::-1]:
        if len(peaks) == n_peaks or explained[k] <= 0:
            break
        if all(abs(int(k) - p) > 2 for p in peaks):
            peaks.append(int(k))
    return [float(2 * np.pi * w[k]) for k in peaks]


def with_modes(model: PolynomialModel, frequencies: list[float], damping: float = INJECTED_DAMPING) -> PolynomialModel:
    """``model`` with a cancelling pole-zero pair per frequency (rad/sample): ``B`` and ``F`` both
    multiplied by ``1 - 2 rho cos(w) q^-1 + rho^2 q^-2``, ``rho = exp(-damping w)``; the same
    response, two orders more per mode."""
    B, F = model.B, model.F
    for w in frequencies:
        rho = np.exp(-damping * w)
        section = np.array([1.0, -2.0 * rho * np.cos(w), rho**2])
        B, F = np.convolve(B, section), np.convolve(F, section)
    return replace(model, B=B, F=F, loss=float("nan"))
