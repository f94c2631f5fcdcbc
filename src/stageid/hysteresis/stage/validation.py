"""Validation of a stage (or rate-independent hysteresis) model on a record that starts mid-history.

A validation record begins after an unknown history: the sensor zero differs from record to
record, the hysteresis memory holds the reversals of whatever ran before, and slow creep lags
or the dynamics may not be at rest.  Like MATLAB's ``compare`` (which estimates a linear
model's initial state by default), :func:`validate_record` estimates these nuisance quantities
on the record, with every model parameter fixed, by least squares:

``initial="kinds"``
    The three standard starting memories of the identification (``"zero"`` demagnetised about
    ``u[0]``, ``"ascending"`` risen from every relay down, ``"descending"`` fallen from every
    relay up), the best one, and one output offset (the mean residual): 1 continuous number.
``initial="estimate"`` (the default)
    The memory chosen from the three kinds and from one earlier minor loop of parametrised
    amplitude -- risen from every relay down to ``M``, fallen to ``m``, risen to ``u[0]``, or
    fallen from every relay up to ``m``, risen to ``M``, fallen to ``u[0]`` -- with ``M >= u[0]
    >= m`` on ``MEMORY_NODES`` evenly spaced levels of the model's input range (2 numbers);
    and, linear in the output, the offset, the initial state of the dynamics (``n`` numbers,
    its free response) and of every creep lag with a non-zero weight (one number each, its
    decaying free response through the dynamics).  ``n_free`` counts them.
``initial="memory"``
    The memory as for ``"estimate"`` and the offset; the dynamics and creep start at rest
    (3 numbers): enough for records that begin after an idle longer than the slowest lag.

The memory is a grid search (the output is piecewise linear in ``M`` and ``m``; the grid's
step is half a cell of a 20-level Preisach model); the linear part is projected out for every
candidate.  Used by ``studies/hysteresis/preisach_stage_study.py`` and ``stageid validate
--initial``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._errors import DataError, ModelError
from . import StageModel
from .dynamics import unit_gain_filter

__all__ = ["validate_record", "RecordValidation", "INITIAL_CHOICES", "MEMORY_NODES"]

INITIAL_CHOICES = ("estimate", "memory", "kinds")
#: Levels of the input range the earlier minor loop's reversal points ``M``, ``m`` are taken from.
MEMORY_NODES = 41
#: Samples x candidates filtered through the dynamics at once (~20 MB).
BLOCK = 2_500_000


@dataclass(frozen=True)
class RecordValidation:
    """Result of :func:`validate_record`.

    Attributes
    ----------
    simulated : ndarray of shape (n_samples,)
        Model output with the estimated initial condition and offset.
    memory : str
        The starting memory: a kind, or ``"rose to M, fell to m, rose to u0"`` /
        ``"fell to m, rose to M, fell to u0"`` with the numbers.
    offset : float
        Output offset added to the model's (sensor zero).
    n_free : int
        Continuous numbers estimated on the record (offset, memory levels, linear states).
    max_error_percent, rms_error_percent : float
        In % of the measured output range.
    """

    simulated: np.ndarray
    memory: str
    offset: float
    n_free: int
    max_error_percent: float
    rms_error_percent: float


def validate_record(
    model: Any, u: object, y: object, dt: float | None = None, initial: str = "estimate"
) -> RecordValidation:
    """Simulate ``model`` on a record with its initial condition estimated on the record (see the module).

    Parameters
    ----------
    model : StageModel, PreisachModel, PIModel or ModifiedPIModel
        Its parameters are not changed.
    u, y : array_like of shape (n_samples,) or (n_samples, 1)
    dt : float, optional
        Sampling period [s] (needed for a model with dynamics or creep; default the model's).
    initial : {"estimate", "memory", "kinds"}, default "estimate"

    Returns
    -------
    RecordValidation

    Raises
    ------
    ModelError
        An unknown ``initial`` or model.
    DataError
        Records of unequal length, non-finite or constant output.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis.preisach import PreisachModel
    >>> from stageid.hysteresis.stage_validation import validate_record
    >>> m = PreisachModel((-1.0, 1.0), np.full(10, 0.1))
    >>> u = 0.5 * np.sin(np.linspace(0, 6, 200))
    >>> y = m.with_state([0.6, -0.3, 0.0]).simulate(u)[:, 0] + 2.0  # an earlier minor loop
    >>> r = validate_record(m, u, y)
    >>> bool(r.rms_error_percent < validate_record(m, u, y, initial="kinds").rms_error_percent)
    True
    """
    if initial not in INITIAL_CHOICES:
        raise ModelError(f"`initial` must be one of {', '.join(INITIAL_CHOICES)}; got {initial!r}.")
    stage = model if isinstance(model, StageModel) else StageModel(model)
    uu = np.asarray(u, dtype=float).reshape(-1)
    yy = np.asarray(y, dtype=float).reshape(-1)
    if uu.shape != yy.shape or uu.size < 2:
        raise DataError(f"input and output must have equal length >= 2; got {uu.size} and {yy.size}.")
    if not (np.all(np.isfinite(uu)) and np.all(np.isfinite(yy))) or not np.ptp(yy) > 0:
        raise DataError("the record must be finite with a varying output.")
    step = stage.dt if dt is None else float(dt)
    h = stage.hysteresis
    memories = candidate_memories(h, uu, initial != "kinds")
    fixed = stage.linear_response(_creep_output(stage, uu, step))  # the creep part, same for every memory
    L = linear_columns(stage, uu.size, step) if initial == "estimate" else np.ones((uu.size, 1))
    Q, _ = np.linalg.qr(L)
    best: Any = None
    labels = list(memories)
    size = max(1, BLOCK // uu.size)
    for start in range(0, len(labels), size):
        block = labels[start : start + size]
        V = np.column_stack([_hysteresis_output(h, memories[k], uu) for k in block])
        E = (yy - fixed)[:, None] - _dynamics(stage, V)
        E -= Q @ (Q.T @ E)
        sse = np.einsum("ij,ij->j", E, E)
        i = int(np.argmin(sse))
        if best is None or sse[i] < best[0]:
            best = (float(sse[i]), block[i])
    label = best[1]
    v = _hysteresis_output(h, memories[label], uu)
    ym = fixed + _dynamics(stage, v[:, None])[:, 0]
    coef = np.linalg.lstsq(L, yy - ym, rcond=None)[0]
    ym = ym + L @ coef
    e = yy - ym
    rng = float(np.ptp(yy))
    n_free = L.shape[1] + (0 if initial == "kinds" else 2)
    return RecordValidation(
        simulated=ym,
        memory=label,
        offset=float(coef[0]),
        n_free=n_free,
        max_error_percent=float(100 * np.max(np.abs(e)) / rng),
        rms_error_percent=float(100 * np.sqrt(np.mean(e**2)) / rng),
    )


def candidate_memories(h: Any, u: np.ndarray, minor_loops: bool) -> dict[str, Any]:
    """The three kinds' states at ``u[0]`` and, with ``minor_loops``, the states after one earlier minor loop."""
    lo, hi = _input_range(h, u)
    u0 = min(max(float(u[0]), lo), hi)
    out = {kind: h.consistent_state(u0, kind) for kind in ("zero", "ascending", "descending")}
    if not minor_loops:
        return out
    nodes = np.linspace(lo, hi, MEMORY_NODES)
    up = h.with_state(h.consistent_state(lo, "ascending"))
    down = h.with_state(h.consistent_state(hi, "descending"))
    for M in nodes[nodes > u0]:
        for m in nodes[nodes < u0]:
            out[f"rose to {M:.4g}, fell to {m:.4g}, rose to {u0:.4g}"] = up.run(np.array([M, m, u0]))[1]
            out[f"fell to {m:.4g}, rose to {M:.4g}, fell to {u0:.4g}"] = down.run(np.array([m, M, u0]))[1]
    return out


def linear_columns(stage: StageModel, n: int, dt: float | None) -> np.ndarray:
    """``[1, free responses of the dynamics' states, free responses of the creep lags]``, shape (n, p)."""
    from scipy.signal import lfilter

    cols = [np.ones(n)]
    b, a = stage.transfer()
    order = max(a.size, b.size) - 1
    for i in range(order):
        zi = np.zeros(order)
        zi[i] = 1.0
        cols.append(lfilter(b, a, np.zeros(n), zi=zi)[0])
    creep = stage.creep_term
    if creep is not None:
        k = np.arange(1, n + 1)
        for p, w in zip(creep.poles(dt), creep.weights):
            if w != 0:  # a lag whose weight is zero does not reach the output
                cols.append(stage.linear_response(p**k))
    return np.column_stack(cols)


def _hysteresis_output(h: Any, memory: Any, u: np.ndarray) -> np.ndarray:
    """The hysteresis output (its own creep included) from ``memory``, shape (n_samples,)."""
    return np.asarray(h.with_state(memory).run(u)[0], dtype=float).reshape(-1)


def _dynamics(stage: StageModel, V: np.ndarray) -> np.ndarray:
    """``y0 + G[V - y0]`` column by column (the stage's linear response of many hysteresis outputs)."""
    if stage.dynamics is None:
        return V
    b, a = stage.transfer()
    return unit_gain_filter(b, a, V)


def _creep_output(stage: StageModel, u: np.ndarray, dt: float | None) -> np.ndarray:
    """The stage's creep contribution, at rest at ``u[0]`` (zero without creep)."""
    creep = stage.creep
    if creep is None:  # a PI model runs its own creep inside ``run``
        return np.zeros(u.size)
    return creep.run(u, dt)[0]


def _input_range(h: Any, u: np.ndarray) -> tuple[float, float]:
    """The hysteresis input range: a Preisach grid's, else the model's limits, else the record's."""
    rng = getattr(h, "input_range", None) or h.input_limits
    if rng is None:
        rng = (float(np.min(u)), float(np.max(u)))
    return float(rng[0]), float(rng[1])
