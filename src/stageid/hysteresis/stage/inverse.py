"""Offline inverse feedforward of a stage model: stable inversion of the dynamics, then the hysteresis inverse.

For a whole reference ``r`` (offline, so preview is allowed):

1. **Dynamics** ``v = y0 + G^-1[r - y0]`` by stable (non-causal) inversion in the frequency
   domain: the reference is padded with its first and last values (the stage rests there), and
   ``V = R conj(G) / (|G|^2 + lambda)`` on the DFT grid.  Unstable zeros of ``G`` (sampled
   zeros outside the unit circle) are inverted without blowing up, the non-causal part giving
   the preview; ``lambda`` (``REGULARISATION`` times ``max |G|^2``) only matters where ``|G|`` is
   tiny (far above the resonance), where no drive could follow anyway.  By default
   (``regularisation="auto"``) it is raised by decades, at most ``AUTO_DECADES`` times, until the
   drive needs no more clipping at the drive limits than the hysteresis inverse of the reference
   itself: an identified ``G`` is least accurate where ``|G|`` is small (near Nyquist, a sampled
   zero near -1), and a drive that saturates there on every corner of a scan rings the stage.
2. **Hysteresis and creep**: the batch compensator of :mod:`.compensator` turns ``v`` into the
   drive, clipped to the drive limits; a Preisach hysteresis is inverted exactly
   (:mod:`.preisach_inverse`), with the stage's creep term folded in per sample
   (:func:`preisach_creep_feedforward`).

References: S. Devasia, D. Chen, B. Paden, "Nonlinear inversion-based output tracking", IEEE
TAC 41 (1996) (stable inversion); M. Tomizuka, ZPETC, ASME JDSMC 109 (1987) (its discrete relative).
"""

from __future__ import annotations

import numpy as np

from ..._errors import ModelError
from ...data.sampling import PERIOD_RTOL, same_period, seconds
from ..inverse.compensator import Compensator
from ..inverse.preisach import PreisachCompensator, preisach_feedforward
from ..models.creep import CreepTerm
from ..models.preisach import PreisachModel
from . import StageModel

__all__ = ["invert_dynamics", "stage_feedforward", "preisach_creep_feedforward", "REGULARISATION", "AUTO_DECADES"]

REGULARISATION = 1e-8
#: Decades ``regularisation="auto"`` may raise ``REGULARISATION`` by.
AUTO_DECADES = 4


def invert_dynamics(model: StageModel, v_out: object, regularisation: float = REGULARISATION) -> np.ndarray:
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
    lam = regularisation * float(np.max(np.abs(G) ** 2))
    V = X * np.conj(G) / (np.abs(G) ** 2 + lam)
    v = np.fft.irfft(V, n)[: x.size] + base
    return v[pad : pad + r.size]


def stage_feedforward(
    model: StageModel,
    y_ref: object,
    dt: float,
    limits: tuple[float, float] | None = None,
    regularisation: float | str = "auto",
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
    regularisation : float or "auto", default "auto"
        ``lambda / max |G|^2`` of the stable inversion; ``"auto"``: the least of
        ``REGULARISATION * 10^k``, ``k <= AUTO_DECADES``, whose drive is clipped no more often
        than the hysteresis inverse of ``y_ref`` alone (module notes).

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
    if model.dt is not None and model.dynamics is not None and not same_period(dt, model.dt):
        raise ModelError(
            f"the reference's sample time {seconds(dt)} s differs from the stage dynamics' {seconds(model.dt)} s "
            f"(tolerance {PERIOD_RTOL:g} relative)."
        )
    off = model.output_offset
    if regularisation != "auto":
        return hysteresis_feedforward(model, off + invert_dynamics(model, ref - off, float(regularisation)), dt, limits)
    if model.dynamics is None:
        return hysteresis_feedforward(model, ref, dt, limits)
    lo, hi = limits if limits is not None else (model.input_limits or (-np.inf, np.inf))
    allowed = clipped_count(hysteresis_feedforward(model, ref, dt, limits), lo, hi)
    for k in range(AUTO_DECADES + 1):
        u = hysteresis_feedforward(model, off + invert_dynamics(model, ref - off, REGULARISATION * 10**k), dt, limits)
        if clipped_count(u, lo, hi) <= allowed:
            break
    return u


def clipped_count(u: np.ndarray, lo: float, hi: float) -> int:
    """Drive samples sitting on a limit (to rounding)."""
    tol = 1e-9 * max(abs(lo), abs(hi), 1.0) if np.isfinite(lo) and np.isfinite(hi) else 0.0
    return int(np.count_nonzero((u <= lo + tol) | (u >= hi - tol)))


def hysteresis_feedforward(
    model: StageModel, v: np.ndarray, dt: float, limits: tuple[float, float] | None
) -> np.ndarray:
    """The drive that makes the stage's hysteresis and creep output ``v`` (shape (n_samples, 1))."""
    if isinstance(model.hysteresis, PreisachModel):
        return preisach_creep_feedforward(model.hysteresis, model.creep, v, dt, limits)
    return Compensator(model.hysteresis, limits=limits, dt=dt).run(v)


def with_linear_part(model: PreisachModel, gain: float) -> PreisachModel:
    """``model(u) + gain u`` on the grid: ``gain h`` added to every diagonal (reversible) cell,
    ``gain lo`` to the offset -- exact for inputs in ``input_range``, where drives stay."""
    n = model.n_levels
    w = np.array(model.weights)
    w[np.arange(n) * (np.arange(n) + 3) // 2] += gain * model.step
    return PreisachModel(
        model.input_range,
        w,
        model.output_offset + gain * model.input_range[0],
        model.state,
        model.inputs,
        model.outputs,
        model.input_limits,
    )


def preisach_creep_feedforward(
    model: PreisachModel, creep: CreepTerm | None, v: object, dt: float, limits: tuple[float, float] | None = None
) -> np.ndarray:
    """Drive, shape (n_samples, 1), with ``model(u) + creep(u) == v`` where reachable (exact).

    The creep's output at sample ``k`` is its memory ``sum_j c_j a_j s_j(k-1)`` plus ``g u(k)``
    (``g = sum_j c_j (1 - a_j)``; at the first sample, at rest, ``(sum_j c_j) u``): the linear
    part is folded into the Preisach diagonal (:func:`with_linear_part`), whose exact inverse
    then gives the drive sample by sample.
    """
    target = np.asarray(v, dtype=float).reshape(-1)
    if creep is None:
        return preisach_feedforward(model, target, limits)
    out = np.empty((target.size, 1))
    if target.size == 0:
        return out
    a = creep.poles(dt)
    c = creep.weights
    ca = c * a
    g = creep.instantaneous_gain(dt)
    comp = PreisachCompensator(with_linear_part(model, g), limits)
    if creep.state is None:  # at rest at the first drive: all of the creep is instantaneous
        first = PreisachCompensator(with_linear_part(model, float(np.sum(c))), limits)
        u = first.step(target[0])
        comp.reset(first.state)
        s = np.full(a.size, u)
    else:
        u = comp.step(target[0] - float(ca @ creep.state))
        s = a * creep.state + (1 - a) * u
    out[0, 0] = u
    for k in range(1, target.size):
        u = comp.step(target[k] - float(ca @ s))
        out[k, 0] = u
        s = a * s + (1 - a) * u
    return out
