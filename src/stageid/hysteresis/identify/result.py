"""The results of the rate-independent identifications: :class:`HysteresisResult` (PI and
modified PI, :mod:`.pi`) and :class:`PreisachResult` (:mod:`.preisach`), on the shared
:class:`RecordsResult` that the stage's result (:mod:`~stageid.hysteresis.stage.result`) uses too.

Each holds the model, each record's errors in % of its output range and its offset, the
records whose error sits at an edge, a copy of the settings it was fitted with, a read-only
``diagnostics`` mapping and a ``summary()``; no training data.  ``HysteresisFit`` and
``PreisachFit`` are the former names of the two classes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...display import html_repr, short_repr
from ...frozen import FrozenMapping
from ...validation.edges import EdgeError
from ..models.preisach import PreisachModel
from .weight_uncertainty import WeightUncertainty

__all__ = ["RecordsResult", "HysteresisResult", "PreisachResult", "HysteresisFit", "PreisachFit"]


@dataclass(frozen=True, repr=False)
class RecordsResult:
    """What every hysteresis result holds: the model and each record's errors and offset.

    Attributes
    ----------
    model
        The identified model.
    max_error_percent, rms_error_percent : tuple of float
        Per record, in % of that record's output range (own offset and starting state).
    output_offsets : tuple of float
        Fitted output offset of each record.

    The subclasses add ``edge_errors`` (records whose error concentrates at their start or end,
    with the trim that removes it, :mod:`stageid.validation.edges`; the summary prints them) and
    ``estimator`` (a copy of the settings of the fit; None for a result built by hand).
    """

    model: Any
    max_error_percent: tuple[float, ...]
    rms_error_percent: tuple[float, ...]
    output_offsets: tuple[float, ...]

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    @property
    def diagnostics(self) -> Mapping[str, Any]:
        """Named figures and notes of the fit (read-only): the worst record's errors and the
        class's own entries (:meth:`diagnostic_items`)."""
        items = {
            "records": len(self.max_error_percent),
            "max_error_percent": max(self.max_error_percent),
            "rms_error_percent": max(self.rms_error_percent),
        }
        return FrozenMapping(items | self.diagnostic_items())

    def diagnostic_items(self) -> dict[str, Any]:
        """The entries of :attr:`diagnostics` particular to the kind of result."""
        return {}

    def record_lines(self, starts: tuple[str, ...] | None = None) -> list[str]:
        """A summary line per record (errors, starting state when given), then its edge notes."""
        lines = []
        for i, (m, r) in enumerate(zip(self.max_error_percent, self.rms_error_percent)):
            start = "" if starts is None else f", start {starts[i]}"
            lines.append(f"  record {i}: max error {m:.3f} % of range, RMS {r:.3f} %{start}")
        return lines + [f"  record {i}: {edge.describe()}" for i, edge in getattr(self, "edge_errors", ())]


@dataclass(frozen=True, repr=False)
class HysteresisResult(RecordsResult):
    """Result of :meth:`PIIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : PIModel or ModifiedPIModel
        The identified model.
    max_error_percent, rms_error_percent, output_offsets
        As :class:`RecordsResult`.
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
    estimator : PIIdentifier or None
        As :class:`RecordsResult`.
    diagnostics : mapping
        ``records``, the worst ``max_error_percent`` and ``rms_error_percent``,
        ``n_evaluations``, ``success`` and ``message``.
    """

    initial_states: tuple[str, ...]
    n_evaluations: int
    success: bool
    message: str
    weight_uncertainty: WeightUncertainty | None = None
    edge_errors: tuple[tuple[int, EdgeError], ...] = ()
    estimator: Any = None

    def diagnostic_items(self) -> dict[str, Any]:
        return {"n_evaluations": self.n_evaluations, "success": self.success, "message": self.message}

    def summary(self) -> str:
        """A short text report."""
        kind = self.model.kind
        lines = [f"{kind} model, {self.model.n_operators} operators; fit on {len(self.max_error_percent)} record(s)"]
        lines += self.record_lines(self.initial_states)
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


@dataclass(frozen=True, repr=False)
class PreisachResult(RecordsResult):
    """Result of :meth:`PreisachIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : PreisachModel
    max_error_percent, rms_error_percent, output_offsets
        As :class:`RecordsResult`.
    filled_cells : int
        Cells the records leave (nearly) undetermined, whose weights the smoothness prior set.
    edge_errors : tuple of (int, EdgeError)
    estimator : PreisachIdentifier or None
        As :class:`RecordsResult`.
    diagnostics : mapping
        ``records``, the worst ``max_error_percent`` and ``rms_error_percent``, ``filled_cells``.
    """

    model: PreisachModel
    filled_cells: int = 0
    edge_errors: tuple[tuple[int, EdgeError], ...] = ()
    estimator: Any = None

    def diagnostic_items(self) -> dict[str, Any]:
        return {"filled_cells": self.filled_cells}

    def summary(self) -> str:
        """A short text report."""
        errs = ", ".join(
            f"{m:.3f} % max / {r:.3f} % rms" for m, r in zip(self.max_error_percent, self.rms_error_percent)
        )
        head = f"Preisach model, {self.model.n_levels} levels ({self.model.n_operators} cells): {errs}"
        if self.filled_cells:
            head += f"; the smoothness prior filled {self.filled_cells} cells the records leave undetermined"
        return "\n".join([head] + [f"  record {i}: {edge.describe()}" for i, edge in self.edge_errors])


#: Former names (kept importable).
HysteresisFit = HysteresisResult
PreisachFit = PreisachResult
