"""The result of :class:`~.identification.StageIdentifier`: the stage model and how it was chosen.

:class:`StageResult` holds the model, each record's errors, offset and starting state, the
dynamics order and creep chosen (with the held-out score of every candidate), the modes taken
from the disturbance spectrum, the records whose error sits at an edge and a copy of the
settings of the fit; ``summary()`` is its text report, ``diagnostics`` a read-only mapping.
``StageFit`` is its former name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...validation.edges import EdgeError
from ..identify.result import RecordsResult
from . import StageModel
from .disturbance_modes import DisturbanceMode
from .dynamics import describe_pole

__all__ = ["StageResult", "StageFit", "SUMMARY_CANDIDATES"]

#: Held-out candidates that :meth:`StageResult.summary` lists (the best ones; the chosen one too).
SUMMARY_CANDIDATES = 3


@dataclass(frozen=True, repr=False)
class StageResult(RecordsResult):
    """Result of :meth:`StageIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : StageModel
    max_error_percent, rms_error_percent, output_offsets
        As :class:`~stageid.hysteresis.identify.result.RecordsResult`.
    initial_states : tuple of str
    dynamics_order : int
        0: no dynamics.
    creep_time_constants : tuple of float
        Empty: no creep.
    held_out : tuple of (int, tuple of float, float)
        ``(order, creep time constants, held-out RMS % summed over folds)`` per candidate when
        something was ``"auto"``; empty otherwise.
    message : str
    modes : tuple of DisturbanceMode
        The modes of the dynamics taken from the records' disturbance spectrum (step 4).
    edge_errors : tuple of (int, EdgeError)
        As :class:`~stageid.hysteresis.identify.result.RecordsResult`.
    chosen : (int, tuple of float) or None
        The ``(order, creep time constants)`` that step 3 chose among ``held_out`` (the
        dynamics' order before any modes; the fitted model may have dropped the dynamics).
    estimator : StageIdentifier or None
        A copy of the settings of the fit (None for a result built by hand).
    diagnostics : mapping
        ``records``, the worst ``max_error_percent`` and ``rms_error_percent``,
        ``dynamics_order``, ``creep_time_constants``, ``modes`` (their count) and ``message``.
    """

    model: StageModel
    initial_states: tuple[str, ...]
    dynamics_order: int
    creep_time_constants: tuple[float, ...]
    held_out: tuple[tuple[int, tuple[float, ...], float], ...]
    message: str
    modes: tuple[DisturbanceMode, ...] = ()
    edge_errors: tuple[tuple[int, EdgeError], ...] = ()
    chosen: tuple[int, tuple[float, ...]] | None = None
    estimator: Any = None

    def diagnostic_items(self) -> dict[str, Any]:
        return {
            "dynamics_order": self.dynamics_order,
            "creep_time_constants": self.creep_time_constants,
            "modes": len(self.modes),
            "message": self.message,
        }

    def summary(self) -> str:
        """A short text report."""
        h = self.model.hysteresis
        size = f"{h.n_levels} levels" if h.kind == "preisach" else f"{h.n_operators} operators"
        lines = [
            f"stage model: {h.kind} hysteresis, {size}; creep "
            + (", ".join(f"{t:g} s" for t in self.creep_time_constants) or "none")
            + f"; dynamics order {self.dynamics_order}; fit on {len(self.max_error_percent)} record(s)"
        ]
        lines += self.record_lines(self.initial_states)
        if self.model.dynamics is not None:
            # by frequency as the continuous equivalent has it; a pole at z = 0 has none and comes last
            poles = sorted(self.model.dynamics.poles(), key=lambda z: abs(np.log(complex(z))) if z != 0 else np.inf)
            lines.append("  dynamics poles at " + ", ".join(describe_pole(z, self.model.dt) for z in poles))
        for m in self.modes:
            lines.append(
                f"  mode from the disturbance spectrum: {m.frequency_hz:.4g} Hz, damping {m.damping:.3g} "
                f"(peak {m.peak_ratio:.3g} x the floor)"
            )
        lines += self.candidate_table(SUMMARY_CANDIDATES)
        lines.append(f"  {self.message}")
        return "\n".join(lines)

    def candidate_table(self, best: int | None = None) -> list[str]:
        """Lines of a table of the held-out candidates, best first: all of them, or the ``best``
        few and the chosen one (a line then says how many were left out).  Empty without any."""
        if not self.held_out:
            return []
        ranked = sorted(self.held_out, key=lambda c: c[2])
        chosen = self.chosen
        shown = [c for i, c in enumerate(ranked) if best is None or i < best or (c[0], tuple(c[1])) == chosen]
        lines = ["  held-out RMS error (% of range, summed over the records left out) of the candidates:"]
        lines.append(f"    {'order':>5}  {'creep time constants [s]':<26}  {'held-out RMS %':>14}")
        for order, taus, score in shown:
            creep = ", ".join(f"{t:g}" for t in taus) or "none"
            mark = "  <- chosen" if (order, tuple(taus)) == chosen else ""
            lines.append(f"    {order:>5}  {creep:<26}  {score:>14.3f}{mark}")
        if len(shown) < len(ranked):
            lines.append(
                f"    ({len(ranked) - len(shown)} more of {len(ranked)} candidates not shown; the HTML report lists all)"
            )
        return lines


#: Former name (kept importable).
StageFit = StageResult
