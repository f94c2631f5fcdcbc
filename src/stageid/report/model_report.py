"""Reports for a user's own identified model: how it looks and how well it predicts data."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .html import Report
from .provenance import settings_section
from .uncertainty import uncertainty_section

__all__ = ["lti_model_report", "hysteresis_model_report", "model_report", "frf_section"]


def _band(model: Any, experiments: Sequence[Any]) -> np.ndarray:
    dt = model.dt if model.dt is not None else (experiments[0].dt if experiments else None)
    fmax = 0.45 / dt if dt else 1000.0
    fmin = fmax / 1e4 if not experiments else max(1.0 / experiments[0].duration, fmax / 1e4)
    return np.geomspace(fmin, fmax, 400)


def lti_model_report(
    model: Any,
    experiments: Sequence[Any] = (),
    title: str = "Identified model",
    notes: Sequence[str] = (),
    uncertainty: Any = None,
    settings: Mapping[str, Any] | None = None,
    command: str | None = None,
) -> tuple[Report, dict[str, Any]]:
    """Bode plot, pole-zero map and, for each experiment, a simulation overlay with fit %.

    ``uncertainty`` (a :class:`~stageid.frf.FrequencyResponse` with ``std``, from a result's
    ``response_uncertainty``) draws the Bode plot on its frequencies with +-2 std bands and
    adds the relative std per entry (:func:`~stageid.report.uncertainty.uncertainty_section`).

    ``settings`` and ``command`` (what made the model) open the report
    (:func:`~stageid.report.provenance.settings_section`).

    Returns the report and a metrics dictionary (fit % per experiment and output).  The fit
    of an output that is constant in an experiment is undefined: NaN in the metrics (``null``
    in ``metrics.json``), "n/a" in the table.
    """
    from ..plots import bode_figure, pzmap_figure

    report = Report(title)
    metrics: dict[str, Any] = {}
    if settings is not None or command:
        settings_section(report, settings or {}, command)
    report.section("Model")
    kind = "continuous" if model.dt is None else f"discrete, Ts = {model.dt:g} s"
    n_states = getattr(model, "n_states", None)
    report.paragraph(
        f"{type(model).__name__}, {kind}; inputs {', '.join(model.inputs)}; outputs {', '.join(model.outputs)}"
        + (f"; {n_states} states." if n_states is not None else ".")
    )
    for note in notes:
        report.paragraph(note)
    units = _channel_units(model, experiments)
    if uncertainty is None:
        f = _band(model, experiments)
        report.figure(
            bode_figure(
                f,
                {"model": model.frequency_response(f)},
                model.inputs,
                model.outputs,
                title="Frequency response",
                **units,
            ),
            "Bode magnitude and phase of the identified model.",
        )
    else:
        uncertainty_section(report, metrics, uncertainty, "identified model", level=3, **units)
    poles, zeros = model.poles(), model.zeros()
    report.figure(
        pzmap_figure({"model": (poles, zeros)}, continuous=model.dt is None, title="Poles and zeros"),
        "Pole-zero map (x poles, o zeros).",
    )
    report.table(
        ["pole", "|pole|" if model.dt is not None else "frequency [Hz]", "damping"],
        [
            [f"{p:.5g}", float(abs(p)) if model.dt is not None else float(abs(p) / (2 * np.pi)), _damping(p, model.dt)]
            for p in poles[:40]
        ],
        caption="Poles (first 40)",
    )
    from .modes import modal_section

    modal_section(report, metrics, model)
    _validation_section(report, metrics, model, experiments)
    return report, metrics


def _channel_units(model: Any, experiments: Sequence[Any]) -> dict[str, tuple[str, ...]]:
    """The units of the model's channels as the first experiment's columns give them ("" unknown)."""
    if not experiments:
        return {"input_units": (), "output_units": ()}
    exp = experiments[0]
    ins = dict(zip(exp.input_names, exp.input_units))
    outs = dict(zip(exp.output_names, exp.output_units))
    return {
        "input_units": tuple(ins.get(n, "") for n in model.inputs),
        "output_units": tuple(outs.get(n, "") for n in model.outputs),
    }


def _validation_section(report: Report, metrics: dict[str, Any], model: Any, experiments: Sequence[Any]) -> None:
    """Simulate the model on each experiment: an overlay figure and the fit % per output.

    A simulation that diverges (an unstable model) gets no fit and no figure, and says so.
    """
    from ..plots import time_overlay_figure
    from ..plots.scale import dominant_period, zoom_window
    from ..validation import fit_percent

    rows = []
    constant: list[str] = []
    diverged: list[str] = []
    for k, exp in enumerate(experiments):
        exp = exp.select(inputs=list(model.inputs), outputs=list(model.outputs))
        y_hat = model.simulate(exp.u, dt=exp.dt)
        if _diverges(y_hat):  # an unstable model: no fit, and no plot of numbers beyond float range
            diverged.append(exp.name or f"experiment {k}")
            for name in model.outputs:
                metrics[f"fit_percent/{exp.name or k}/{name}"] = float("nan")
                rows.append([exp.name or f"experiment {k}", name, float("nan")])
            continue
        fit = fit_percent(exp.y, y_hat)
        for name, value in zip(model.outputs, fit):
            metrics[f"fit_percent/{exp.name or k}/{name}"] = float(value)
            rows.append([exp.name or f"experiment {k}", name, float(value)])
            if np.isnan(value):
                constant.append(f"{name} in {exp.name or f'experiment {k}'}")
        # past about four thousand samples (two per pixel) a fast signal drawn whole is a solid block
        period = dominant_period(exp.y, exp.dt) if exp.n_samples > 4000 else None
        window = None if period is None else zoom_window(exp.time, period)
        report.figure(
            time_overlay_figure(
                exp.time,
                exp.y,
                {"simulated": y_hat},
                exp.output_names,
                exp.output_units,
                title=f"Simulation on {exp.name or f'experiment {k}'}",
                window=window,
            ),
            f"Measured outputs of {exp.name or f'experiment {k}'} with the model's simulation (from rest) and the error"
            + (
                "."
                if window is None
                else f": the last three periods ({window[0]:.4g}-{window[1]:.4g} s) above, the error over the "
                "whole record (its min-max envelope) below."
            ),
        )
    if rows:
        report.section("Validation")
        report.table(
            ["experiment", "output", "fit [%]"], rows, caption="Simulation fit, 100 (1 - |y - y_sim| / |y - mean y|)"
        )
        if constant:
            report.paragraph(
                "n/a: the fit is undefined for an output that does not move in the data (" + "; ".join(constant) + ")."
            )
        if diverged:
            report.paragraph(
                "n/a: the model's simulation diverges on "
                + "; ".join(diverged)
                + " (an unstable model): no fit, no plot."
            )


#: Lines of a measured response whose coherence is below this are noise, not response (an
#: unexcited band): they are drawn but not counted in the model-against-data error.
COHERENT = 0.8


def frf_section(
    report: Report,
    metrics: dict[str, Any],
    model: Any,
    frd: Any,
    source: str = "measured",
    prefix: str = "",
    level: int = 2,
    input_units: Sequence[str] = (),
    output_units: Sequence[str] = (),
) -> None:
    """The measured frequency response (``frd``, a :class:`~stageid.frf.FrequencyResponse` with
    the model's channels) beside the model: Bode figure with its +-2 std band and coherence,
    and per input column the largest ``|G_model - G_measured|`` over the column's peak, on the
    lines where every output's coherence is at least ``COHERENT`` (all lines without coherence)."""
    from ..frf.identification import column_errors
    from .frd_report import frf_caption

    keep = np.ones(frd.freqs.size, bool) if frd.coherence is None else np.all(frd.coherence >= COHERENT, axis=1)
    report.section("Measured frequency response", level)
    report.figure(
        frd.plot(model=model, input_units=input_units, output_units=output_units),
        frf_caption(frd, source[:1].upper() + source[1:]) + " Dashed: the model.",
    )
    if frd.total_std is not None:
        from ..frf.bla_figure import bla_figure

        report.figure(
            bla_figure(frd),
            f"Best linear approximation ({source}): |BLA| (line), total distortion level from the "
            "realisation-to-realisation scatter (red) and noise level from the period-to-period scatter "
            "(green); where red stands above green the stage's nonlinearity, not noise, sets the scatter.",
        )
    if not np.any(keep):
        report.paragraph(f"No line of the {source} response has coherence >= {COHERENT}: no error is computed.")
        return
    errors = column_errors(model.frequency_response(frd.freqs[keep]), frd.response[keep])
    rows = [[inp, float(100 * e)] for inp, e in zip(frd.inputs, errors)]
    counted = (
        "all lines" if frd.coherence is None else f"{int(keep.sum())} of {keep.size} lines, coherence >= {COHERENT}"
    )
    report.table(
        ["input", "max |model - measured| [% of peak]"],
        rows,
        caption=f"Model against the {source} response ({counted})",
    )
    for inp, e in zip(frd.inputs, errors):
        metrics[f"{prefix}frf/column_error_percent/{inp}"] = float(100 * e)


def _diverges(y: np.ndarray) -> bool:
    """True when a simulation did not stay finite (an unstable model): nothing to fit or plot."""
    return not np.all(np.isfinite(y))


def _damping(p: complex, dt: float | None) -> float:
    s = p if dt is None else (np.log(p) / dt if p != 0 else -np.inf)
    mag = abs(s)
    return float(-s.real / mag) if np.isfinite(mag) and mag > 0 else float("nan")


def hysteresis_model_report(
    model: Any,
    records: Sequence[Any] = (),
    title: str = "Hysteresis model",
    uncertainty: Any = None,
    settings: Mapping[str, Any] | None = None,
    command: str | None = None,
) -> tuple[Report, dict[str, Any]]:
    """Measured versus modelled input-output loops and the modelling error in % of range.

    When a record's output does not move its range is zero: the error in % of range is
    undefined (NaN in the metrics, ``null`` in ``metrics.json``) and the error is plotted in
    the output's own unit.  ``uncertainty`` (the fit's
    :class:`~stageid.hysteresis.weight_uncertainty.WeightUncertainty`) draws the band the weights' uncertainty puts
    on each simulated loop (:func:`~stageid.report.uncertainty.loop_band_figure`) and reports its
    half-width and how much of the record it holds.  A stage model's dynamics (Bode, modes) and
    a creep term (step response) get their own figures; ``settings`` and ``command`` open the
    report as in :func:`lti_model_report`.
    """
    from ..plots.hysteresis import loop_error_figure
    from .uncertainty import LOOP_N_STD, loop_band_figure

    report = Report(title)
    metrics: dict[str, Any] = {}
    if settings is not None or command:
        settings_section(report, settings or {}, command)
    report.section("Model")
    report.paragraph(f"{type(model).__name__}; input {model.inputs[0]}, output {model.outputs[0]}.")
    band_rows = []
    for k, exp in enumerate(records):
        name = exp.name or k
        u = exp.u[:, 0]
        y = exp.y[:, 0]
        if uncertainty is not None:
            y_hat, std = uncertainty.output_band(model, exp.u, exp.dt)
        else:
            y_hat, std = model.simulate(exp.u)[:, 0], None
        y_range = float(np.ptp(y))
        err, err_scale, err_label, err_text = _record_error(y, y_hat, exp.output_units[0] or "output unit")
        metrics[f"max_error_percent_range/{name}"] = err
        labels = (
            f"{model.inputs[0]} [{exp.input_units[0] or 'input unit'}]",
            f"{model.outputs[0]} [{exp.output_units[0] or 'output unit'}]",
        )
        if std is not None:
            half = LOOP_N_STD * std * (100.0 / y_range if y_range > 0 else float("nan"))
            inside = float(np.mean(np.abs(y - y_hat) <= LOOP_N_STD * std))
            metrics[f"loop_band/median_half_width_percent_range/{name}"] = float(np.median(half))
            metrics[f"loop_band/max_half_width_percent_range/{name}"] = float(np.max(half))
            metrics[f"loop_band/error_inside_percent/{name}"] = 100 * inside
            band_rows.append([exp.name or f"record {k}", float(np.median(half)), float(np.max(half)), 100 * inside])
            report.figure(
                loop_band_figure(u, y, y_hat, std, exp.time, labels, y_range),
                f"{exp.name or f'record {k}'}: loops with the band of +-{LOOP_N_STD:g} std that the weights' "
                f"uncertainty ({uncertainty.method}) puts on the simulated output, and the modelling error "
                f"inside it ({err_text}).",
            )
            continue
        report.figure(
            loop_error_figure(exp.time, u, y, y_hat, labels, err_label, scale=err_scale),
            f"{exp.name or f'record {k}'}: loops and modelling error ({err_text}); a long record of a fast input "
            "in a window of its last periods beside the whole record's error envelope.",
        )
    from .stage_report import stage_parts_section

    units = (records[0].input_units[0], records[0].output_units[0]) if records else ("", "")
    stage_parts_section(report, metrics, model, *units)
    _weights_band_table(report, band_rows, LOOP_N_STD)
    return report, metrics


def _weights_band_table(report: Report, band_rows: list, n_std: float) -> None:
    if band_rows:
        report.section("Uncertainty of the weights")
        report.table(
            ["record", "median half-width [% of range]", "max half-width [% of range]", "error inside [% of samples]"],
            band_rows,
            caption=f"+-{n_std:g} std band of the simulated output from the weights' covariance; it says how "
            "well the data fix the weights, not how wrong the model's structure is",
        )


def _record_error(y: np.ndarray, y_hat: np.ndarray, unit: str) -> tuple[float, float, str, str]:
    """Max error in % of the output's range, the factor from output units to the error axis's,
    its label and the caption text; in the output's ``unit`` when the output does not move (the
    % is then undefined: NaN)."""
    y_range = float(np.ptp(y))
    if y_range > 0:
        err = 100.0 * float(np.max(np.abs(y - y_hat))) / y_range
        # three decimals, as the fit summary prints it
        return err, 100.0 / y_range, "error [% of range]", f"max {err:.3f} % of range"
    text = f"% of range n/a: the output does not move; max {float(np.max(np.abs(y - y_hat))):.4g} {unit}"
    return float("nan"), 1.0, f"error [{unit}]", text


def model_report(
    model: Any,
    experiments: Sequence[Any] = (),
    title: str | None = None,
    uncertainty: Any = None,
    settings: Mapping[str, Any] | None = None,
    command: str | None = None,
) -> tuple[Report, dict[str, Any]]:
    """A report for any stageid model: LTI models get Bode/pole-zero/simulation (with ``uncertainty``
    bands when given, a FrequencyResponse, see :func:`lti_model_report`), hysteresis models loops
    (with the band of a :class:`~stageid.hysteresis.weight_uncertainty.WeightUncertainty` ``uncertainty``)."""
    if hasattr(model, "frequency_response"):
        return lti_model_report(
            model,
            experiments,
            title or "Identified LTI model",
            uncertainty=uncertainty,
            settings=settings,
            command=command,
        )
    return hysteresis_model_report(
        model, experiments, title or "Identified hysteresis model", uncertainty, settings, command
    )
