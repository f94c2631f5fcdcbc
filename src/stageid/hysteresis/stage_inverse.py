"""Offline inverse feedforward of a stage model: stable inversion of the dynamics, then the hysteresis inverse.

For a whole reference ``r`` (offline, so preview is allowed):

1. **Dynamics** ``v = y0 + G^-1[r - y0]`` by stable (non-causal) inversion in the frequency
   domain: the reference is padded with its first and last values (the stage rests there), and
   ``V = R conj(G) / (|G|^2 + lambda)`` on the DFT grid.  Unstable zeros of ``G`` (sampled
   zeros outside the unit circle) are inverted without blowing up, the non-causal part giving
   the preview; ``lambda`` (``REGULARISATION`` times ``max |G|^2``) only matters where ``|G|`` is
   tiny (far above the resonance), where no drive could follow anyway.
2. **Hysteresis and creep**: the batch compensator of :mod:`.compensator` turns ``v`` into the
   drive, clipped to the drive limits.

References: S. Devasia, D. Chen, B. Paden, "Nonlinear inversion-based output tracking", IEEE
TAC 41 (1996) (stable inversion); M. Tomizuka, ZPETC, ASME JDSMC 109 (1987) (its discrete relative).
"""

from __future__ import annotations

import numpy as np

from .._errors import ModelError
from .compensator import Compensator
from .stage import StageModel

__all__ = ["invert_dynamics", "stage_feedforward", "REGULARISATION"]

REGULARISATION = 1e-8


def invert_dynamics(model: StageModel, v_out: object) -> np.ndarray:
    """``y0 + G^-1[v_out - y0]`` of shape (n_samples,) by padded frequency-domain stable inversion."""
    r = np.asarray(v_out, dtype=float).reshape(-1)
    if model.dynamics is None or r.size == 0:
        return r.copy()
    b, a = model.transfer()
    poles = np.abs(model.dynamics.poles())
    slowest = 1.0 / max(1e-6, 1.0 - float(np.max(poles))) if poles.size else 1.0
    pad = int(min(max(2000, 20 * slowest), 200000))
    x = np.concatenate([np.full(pad, r[0]), r, np.full(pad, r[-1])])
    base = x[0]
    n = 1 << int(np.ceil(np.log2(x.size)))
    X = np.fft.rfft(x - base, n)
    zinv = np.exp(-2j * np.pi * np.arange(X.size) / n)
    G = np.polyval(b[::-1], zinv) / np.polyval(a[::-1], zinv)
    lam = REGULARISATION * float(np.max(np.abs(G) ** 2))
    V = X * np.conj(G) / (np.abs(G) ** 2 + lam)
    v = np.fft.irfft(V, n)[: x.size] + base
    return v[pad : pad + r.size]


def stage_feedforward(
    model: StageModel, y_ref: object, dt: float, limits: tuple[float, float] | None = None
) -> np.ndarray:
    """The drive, shape (n_samples, 1), that makes the stage model follow ``y_ref`` (offline).

    Parameters
    ----------
    model : StageModel
    y_ref : array_like of shape (n_samples,) or (n_samples, 1)
        Desired outputs (finite).
    dt : float
        Sampling period [s] of ``y_ref``; must equal the model's when it has dynamics.
    limits : (float, float), optional
        Drive limits; default the hysteresis model's ``input_limits``.

    Raises
    ------
    ModelError
        Non-finite reference, a ``dt`` other than the model's, or a non-invertible hysteresis.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.stage import StageModel
    >>> from stageid.hysteresis.stage_inverse import stage_feedforward
    >>> from stageid.models import StateSpaceModel
    >>> s = StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]),
    ...                StateSpaceModel([[0.5]], [[1.0]], [[0.5]], [[0.0]], dt=1e-3))
    >>> ref = np.sin(np.linspace(0, 2 * np.pi, 400)) ** 2
    >>> u = stage_feedforward(s, ref, 1e-3)
    >>> bool(np.max(np.abs(s.simulate(u, 1e-3)[:, 0] - ref)[20:-20]) < 1e-3)
    True
    """
    ref = np.asarray(y_ref, dtype=float).reshape(-1)
    if not np.all(np.isfinite(ref)):
        raise ModelError("the reference must be finite; got NaN or inf.")
    if model.dt is not None and model.dynamics is not None and not np.isclose(dt, model.dt, rtol=1e-6):
        raise ModelError(f"the reference's sample time {dt:g} s differs from the stage dynamics' {model.dt:g} s.")
    off = model.output_offset
    v = off + invert_dynamics(model, ref - off)
    return Compensator(model.hysteresis, limits=limits, dt=dt).run(v)
