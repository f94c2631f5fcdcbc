"""The parts of a hysteresis or stage model in a report: fit summary, linear dynamics, creep, modes."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .html import Report

__all__ = ["fit_summary_section", "stage_parts_section"]


def fit_summary_section(report: Report, fit: Any, record_names: Sequence[str], level: int = 2) -> None:
    """A hysteresis fit's summary as a per-record table and a list (one item per line of the
    ``summary()`` text), not one paragraph."""
    report.section("Identification", level)
    lines = [line.strip() for line in fit.summary().splitlines() if line.strip()]
    per_record = getattr(fit, "max_error_percent", ())
    if per_record:
        rms = getattr(fit, "rms_error_percent", (float("nan"),) * len(per_record))
        starts = getattr(fit, "initial_states", ("",) * len(per_record))
        names = list(record_names) + [f"record {k}" for k in range(len(record_names), len(per_record))]
        report.table(
            ["record", "max error [% of range]", "RMS error [% of range]", "starting state"],
            # three decimals, as the command line's summary prints them
            [[n, f"{m:.3f}", f"{r:.3f}", s] for n, m, r, s in zip(names, per_record, rms, starts)],
            caption="Fit on each identification record",
        )
        # the table holds the per-record lines; the list keeps the rest in the summary's order
        lines = [line for line in lines if not line.startswith("record ")]
    report.bullets(lines)


def stage_parts_section(
    report: Report, metrics: dict[str, Any], model: Any, input_unit: str = "", output_unit: str = "", level: int = 2
) -> None:
    """Figures of what a model has besides its loops: the linear dynamics' Bode plot with the
    disturbance modes marked (and listed), and the creep term's step response."""
    from ..plots.hysteresis import creep_figure, stage_dynamics_figure
    from ..plots.scale import magnitude_unit

    dynamics = getattr(model, "dynamics", None)
    creep = getattr(model, "creep_term", None) or getattr(model, "creep", None)
    if dynamics is None and creep is None:
        return
    report.section("Dynamics and creep of the model", level)
    if dynamics is not None and dynamics.n_states > 0:
        modes = tuple(getattr(model, "disturbance_modes", ()))
        report.figure(
            stage_dynamics_figure(model, output_unit),
            f"Linear dynamics from the hysteresis output to the stage output (order {dynamics.n_states}, "
            f"unit DC gain, Ts = {dynamics.dt:g} s), up to the Nyquist frequency"
            + (
                "; dotted: the modes taken from the records' disturbance spectrum."
                if modes
                else "; no mode was taken from the disturbance spectrum."
            ),
        )
        from .modes import modal_section

        modal_section(report, metrics, dynamics, prefix="dynamics/")
        if modes:
            report.table(
                ["disturbance mode", "frequency [Hz]", "damping [-]"],
                [[k + 1, f, z] for k, (f, z) in enumerate(modes)],
                caption="Modes the identification took from the residual's disturbance spectrum (part of the dynamics)",
            )
            metrics["disturbance_modes/frequency_hz"] = [f for f, _ in modes]
    if creep is not None:
        report.figure(
            creep_figure(creep, input_unit, output_unit),
            f"Creep term: output after a unit step of the input, {creep.n_lags} first-order lags "
            f"(time constants {', '.join(f'{t:g}' for t in creep.time_constants)} s); total creep gain "
            f"{float(sum(creep.weights)):.3g} {output_unit or 'output unit'} per {input_unit or 'input unit'}.",
        )
        metrics["creep/total_gain"] = float(sum(creep.weights))
        report.unit("creep/total_gain", magnitude_unit(output_unit, input_unit))
