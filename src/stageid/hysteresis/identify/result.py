"""The results of the rate-independent identifications: :class:`HysteresisFit` (PI and
modified PI, :mod:`.pi`) and :class:`PreisachFit` (:mod:`.preisach`).

Each holds the model, each record's errors in % of its output range and its offset, the
records whose error sits at an edge, and a ``summary()``; no training data.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...display import html_repr, short_repr
from ...validation.edges import EdgeError
from ..models.preisach import PreisachModel
from .weight_uncertainty import WeightUncertainty

__all__ = ["HysteresisFit", "PreisachFit"]


@dataclass(frozen=True)
class HysteresisFit:
    """Result of :meth:`PIIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : PIModel or ModifiedPIModel
        The identified model.
    max_error_percent, rms_error_percent : tuple of float
        Per identification record, in % of that record's output range.
    output_offsets : tuple of float
        Fitted output offset of each record.
    initial_states : tuple of str
        Starting-state kind of each record.
    n_evaluations : int
        Weight fits done by the nonlinear search (0 for the classical model).
    success : bool
        False when the nonlinear search stopped on its evaluation limit (the model is still the
        best found and never worse than the classical fit it started from).
    message : str
    weight_uncertainty : WeightUncertainty or None
        Covariance of the weights (when asked for; :mod:`.weight_uncertainty`), with the band
        of a simulated output by ``weight_uncertainty.output_band(model, u)``.
    edge_errors : tuple of (int, EdgeError)
        Records whose error concentrates at their start or end, with the trim that removes it
        (:mod:`stageid.validation.edges`); the summary prints them.
    """

    model: Any
    max_error_percent: tuple[float, ...]
    rms_error_percent: tuple[float, ...]
    output_offsets: tuple[float, ...]
    initial_states: tuple[str, ...]
    n_evaluations: int
    success: bool
    message: str
    weight_uncertainty: WeightUncertainty | None = None
    edge_errors: tuple[tuple[int, EdgeError], ...] = ()

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def summary(self) -> str:
        """A short text report."""
        kind = self.model.kind
        lines = [f"{kind} model, {self.model.n_operators} operators; fit on {len(self.max_error_percent)} record(s)"]
        for i, (m, r, s) in enumerate(zip(self.max_error_percent, self.rms_error_percent, self.initial_states)):
            lines.append(f"  record {i}: max error {m:.3f} % of range, RMS {r:.3f} %, start {s}")
        lines += [f"  record {i}: {edge.describe()}" for i, edge in self.edge_errors]
        if kind == "modified-pi":
            lines.append(
                f"  rc/r = {_ratio(self.model.rc, self.model.r):.4f}, ra/r = {_ratio(self.model.ra, self.model.r):.4f}, "
                f"rb/ra = {_ratio(self.model.rb, self.model.ra):.4f}, centre = {self.model.input_offset:.6g}, "
                f"input warp = {self.model.input_warp:.4f}"
            )
        creep = getattr(self.model, "creep", None)
        if creep is not None:
            lines.append(
                "  creep: " + ", ".join(f"{c:.4g} at {t:g} s" for t, c in zip(creep.time_constants, creep.weights))
            )
        lines.append(f"  {self.message}")
        return "\n".join(lines)


def _ratio(a: np.ndarray, b: np.ndarray) -> float:
    k = b > 0
    return float(np.median(a[k] / b[k])) if np.any(k) else float("nan")


@dataclass(frozen=True)
class PreisachFit:
    """Result of :meth:`PreisachIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : PreisachModel
    max_error_percent, rms_error_percent : tuple of float
        Per record, in % of that record's output range.
    output_offsets : tuple of float
        Fitted output offset of each record.
    filled_cells : int
        Cells the records leave (nearly) undetermined, whose weights the smoothness prior set.
    edge_errors : tuple of (int, EdgeError)
        Records whose error concentrates at their start or end, with the trim that removes it
        (:mod:`stageid.validation.edges`); the summary prints them.
    """

    model: PreisachModel
    max_error_percent: tuple[float, ...]
    rms_error_percent: tuple[float, ...]
    output_offsets: tuple[float, ...]
    filled_cells: int = 0
    edge_errors: tuple[tuple[int, EdgeError], ...] = ()

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def summary(self) -> str:
        errs = ", ".join(
            f"{m:.3f} % max / {r:.3f} % rms" for m, r in zip(self.max_error_percent, self.rms_error_percent)
        )
        head = f"Preisach model, {self.model.n_levels} levels ({self.model.n_operators} cells): {errs}"
        if self.filled_cells:
            head += f"; the smoothness prior filled {self.filled_cells} cells the records leave undetermined"
        return "\n".join([head] + [f"  record {i}: {edge.describe()}" for i, edge in self.edge_errors])
