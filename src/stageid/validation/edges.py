"""Errors that concentrate at the edges of a record: a start-up transient or an end glitch.

Measured records often start with something no model of the stage describes (a sensor settling
after the capture starts, the step onto the initial voltage) or end on a sample where the drive
was reset.  One such sample can set the max error of a whole fit.  The rule, one for every fit
that reports it:

* the **edges** are the first and the last ``EDGE_FRACTION`` (5 %) of the samples, the
  **middle** is the rest;
* an edge holds a transient when its largest absolute error is more than ``EDGE_RATIO`` (3)
  times the largest of the middle *and* at least ``EDGE_FLOOR_PERCENT`` (1 %) of the output
  range (smaller errors are not worth trimming data for);
* the transient runs from the record's edge inward up to the last sample whose error exceeds the
  middle's largest, and ends once the error has stayed within it for ``SETTLE_FRACTION``
  (0.5 %, at least 10) samples: the trim (``start`` / ``stop``) drops exactly that run.  A
  ringing transient crosses zero, so one sample within the bound is not its end; ordinary fit
  error deeper in the edge, beyond such a settled stretch, is not part of it (on the dSPACE
  feedforward records a one-sample end glitch would otherwise stretch to 1000 samples).

A hint, never a change: the fit itself uses every sample it was given.  An LTI model is judged
on its response from each record's estimated initial state (:mod:`.initial_state`), so a record
that starts in motion is not blamed for the model's start from rest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "EDGE_FRACTION",
    "EDGE_RATIO",
    "EDGE_FLOOR_PERCENT",
    "SETTLE_FRACTION",
    "EdgeError",
    "edge_errors",
    "edge_lines",
    "lti_edge_lines",
]

EDGE_FRACTION = 0.05
EDGE_RATIO = 3.0
EDGE_FLOOR_PERCENT = 1.0
SETTLE_FRACTION = 0.005
MIN_SAMPLES = 40  # below this, 5 % edges are one or two samples: no basis for a rule


@dataclass(frozen=True)
class EdgeError:
    """An error concentrated at one edge of a record (see the module notes for the rule).

    Attributes
    ----------
    edge : {"start", "stop"}
        Which edge, named after the option that trims it.
    n_samples : int
        Samples to drop at that edge.
    edge_percent, rest_percent : float
        Largest absolute error in the edge and in the middle, in % of the output range.
    trim_at : float or None
        Time [s] on the record's axis to pass as ``start``/``stop`` (the first/last sample
        kept); None when the record has no time axis.
    """

    edge: str
    n_samples: int
    edge_percent: float
    rest_percent: float
    trim_at: float | None = None

    def describe(self) -> str:
        """One line: where the error is, how large against the rest, and the trim that removes it.

        Examples
        --------
        >>> from stageid.validation.edges import EdgeError
        >>> EdgeError("start", 336, 35.3, 3.3, 0.0336).describe()
        'max error in the first 336 samples (35.3 % of range there, at most 3.3 % in the middle 90 %): a start-up transient; try `start=0.0336`'
        """
        where, what = ("first", "a start-up transient") if self.edge == "start" else ("last", "an end transient")
        samples = "sample" if self.n_samples == 1 else f"{self.n_samples} samples"
        trim = f"`{self.edge}={self.trim_at:.6g}`" if self.trim_at is not None else "dropping those samples"
        return (
            f"max error in the {where} {samples} ({self.edge_percent:.1f} % of range there, "
            f"at most {self.rest_percent:.1f} % in the middle {100 - 200 * EDGE_FRACTION:g} %): {what}; try {trim}"
        )


def edge_errors(
    error: np.ndarray, output_range: float, dt: float | None = None, t0: float = 0.0
) -> tuple[EdgeError, ...]:
    """The edges of a record whose error is a transient, by the rule of the module notes.

    Parameters
    ----------
    error : array_like of shape (n_samples,)
        Measured minus predicted output.
    output_range : float
        The measured output's range (peak to peak), > 0: the errors' scale.
    dt, t0 : float, optional
        The record's sample time and first time stamp [s], for :attr:`EdgeError.trim_at`.

    Returns
    -------
    tuple of EdgeError
        Empty when neither edge holds a transient (or the record has fewer than 40 samples).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.validation.edges import edge_errors
    >>> e = 0.01 * np.sin(np.arange(1000.0))
    >>> e[:20] = 0.5  # a transient in the first 20 samples
    >>> [(x.edge, x.n_samples, x.trim_at) for x in edge_errors(e, 1.0, dt=0.001)]
    [('start', 20, 0.02)]
    """
    a = np.abs(np.asarray(error, dtype=float).reshape(-1))
    n = a.size
    if n < MIN_SAMPLES or not output_range > 0:
        return ()
    h = max(int(np.ceil(EDGE_FRACTION * n)), 1)
    rest = float(np.max(a[h : n - h]))
    found = []
    for edge, part in (("start", a[:h]), ("stop", a[n - h :])):
        peak = float(np.max(part))
        if not (peak > EDGE_RATIO * rest and 100.0 * peak / output_range >= EDGE_FLOOR_PERCENT):
            continue
        settle = max(int(np.ceil(SETTLE_FRACTION * n)), 10)
        count = _transient_length(part if edge == "start" else part[::-1], rest, settle)
        kept = count if edge == "start" else n - count - 1  # index of the first / last sample kept
        trim_at = None if dt is None else float(t0 + kept * dt)
        found.append(EdgeError(edge, count, 100.0 * peak / output_range, 100.0 * rest / output_range, trim_at))
    return tuple(found)


def _transient_length(inward: np.ndarray, bound: float, settle: int) -> int:
    """Samples from the edge (``inward[0]``) to the last above ``bound`` before ``settle`` in a row within it."""
    count = run = 0
    for k, above in enumerate(inward > bound):
        if above:
            count, run = k + 1, 0
        else:
            run += 1
            if run >= settle:
                break
    return count


def edge_lines(experiments: Sequence[Any], simulated: Sequence[np.ndarray], outputs: Sequence[str]) -> list[str]:
    """``"<record>  <output>: <hint>"`` for each record and output whose error is an edge transient.

    ``simulated[k]`` (n_samples, n_outputs) is the model's output on ``experiments[k]`` (an
    :class:`~stageid.data.Experiment`: its ``y``, ``dt``, ``t0`` and ``name`` are used).
    """
    lines = []
    for exp, ys in zip(experiments, simulated):
        error = np.asarray(exp.y, dtype=float) - np.asarray(ys, dtype=float).reshape(exp.y.shape)
        for i, name in enumerate(outputs):
            for edge in edge_errors(error[:, i], float(np.ptp(exp.y[:, i])), exp.dt, exp.t0):
                lines.append(f"{exp.name}  {name}: {edge.describe()}")
    return lines


def lti_edge_lines(model: Any, experiments: Sequence[Any]) -> list[str]:
    """:func:`edge_lines` of an LTI model, simulated on each record from its estimated initial state;
    none for an unstable model (its simulation diverges: no edge to blame)."""
    from .initial_state import simulate_from_estimated_state

    if not model.is_stable():
        return []
    simulated = [simulate_from_estimated_state(model, e.u, e.y, e.dt) for e in experiments]
    return edge_lines(experiments, simulated, model.outputs)
