"""``stageid validate``: does a model explain the data?  Fit, RMS error and residual tests (MATLAB ``resid``)."""

from __future__ import annotations

import click

from .._errors import DataError
from ..validation.residuals import ALPHA, MAX_LAG
from ._common import MODEL_CHANNELS_HELP, channel_options, read_experiments, say, split_names, trim_options
from .outputs import check_output, check_output_folder


@click.command(
    "validate",
    epilog="""
\b
Examples:
  stageid validate model.json val.csv
  stageid validate model.json a.csv b.csv --json validation.json --report val-report/
  stageid validate hyst.json drive.csv --inputs V --outputs z --ts 0.002
  stageid validate model.json val.csv --start 0.5 --stop 1.5     # only 0.5 s to 1.5 s of the record
""",
)
@click.argument("model_path", metavar="MODEL.json", type=click.Path(dir_okay=False))
@click.argument("data", nargs=-1, required=True, type=click.Path(dir_okay=False))
@channel_options(
    *MODEL_CHANNELS_HELP, "Sample time [s] when the files have no `t` column (default: a discrete model's)."
)
@click.option(
    "--initial",
    type=click.Choice(["estimate", "memory", "kinds", "model"]),
    default=None,
    help="The record's initial condition.  LTI models: model (default: from rest) or estimate (the "
    "least-squares initial state of each record, as MATLAB's compare 'e').  Hysteresis and stage models: "
    "estimate (default, as MATLAB's compare): offset, hysteresis memory (the three kinds or one earlier "
    "minor loop) and the dynamics' and creep states fitted on each record; memory: offset and memory only; "
    "kinds: offset and the best of the three standard memories; model: the model's own state and offset.",
)
@click.option("--json", "json_out", default=None, type=click.Path(dir_okay=False), help="Write the results as JSON.")
@click.option(
    "--report", "report_dir", default=None, type=click.Path(file_okay=False), help="Folder for an HTML report."
)
@trim_options
def validate_command(
    model_path: str,
    data: tuple[str, ...],
    inputs: str | None,
    outputs: str | None,
    ts: float | None,
    initial: str | None,
    json_out: str | None,
    report_dir: str | None,
) -> None:
    """Simulate MODEL.json on each DATA record: per output fit % (as MATLAB's compare), RMS error in
    % of the measured range, whiteness of the residual (Ljung-Box chi-square over lags 1..25) and
    its independence from each input (chi-square over lags 0..25, input prewhitened), each at the
    1 % level.  A correct model passes both about 99 % of the time.  One line per record and
    output, then one per output over all records pooled."""
    from ..atomic import atomic_write_text
    from ..models import load_model
    from ..report.html import metrics_json
    from ..validation.residuals import validate_model, validation_json

    if json_out is not None:
        check_output(json_out, "model")
    if report_dir is not None:
        check_output_folder(report_dir)
    model = load_model(model_path)
    hysteresis = not hasattr(model, "frequency_response")
    if initial not in (None, "model", "estimate") and not hysteresis:
        raise click.UsageError(
            f"--initial {initial} is for hysteresis and stage models; an LTI model takes model or estimate."
        )
    experiments = _experiments(model, data, inputs, outputs, ts)
    records = _initial_conditions(model, experiments, initial or "estimate") if hysteresis else None
    simulated = None if records is None else [r.simulated for r in records]
    if not hysteresis and initial == "estimate":
        from ..validation.initial_state import simulate_from_estimated_state

        simulated = [simulate_from_estimated_state(model, e.u, e.y, e.dt) for e in experiments]
    result = validate_model(model, experiments, MAX_LAG, ALPHA, simulated=simulated)
    summary = validation_json(result)
    if not hysteresis:
        summary["initial"] = {"method": initial or "model"}
    if len(experiments) > 1:
        summary["records"] = _per_record(model, experiments, result["simulated"])
    if hysteresis:
        _hysteresis_metrics(summary, experiments, result)
        if records is not None:
            summary["initial"] = {
                "method": initial or "estimate",
                "records": [
                    {"record": e.name, "memory": r.memory, "offset": r.offset, "n_free": r.n_free}
                    for e, r in zip(experiments, records)
                ],
            }
    if json_out is not None:
        atomic_write_text(json_out, metrics_json(summary))
    if report_dir is not None:
        path = _write_report(report_dir, model, experiments, result, summary)
        say(f"report written to {path}")
    say(_summary_text(summary, [e.name for e in experiments]))
    for line in _edge_lines(model, experiments, result["simulated"]):
        say(line)


def _edge_lines(model, experiments, simulated) -> list[str]:
    """A line per record and output whose error concentrates at an edge (:mod:`stageid.validation.edges`);
    an LTI model from each record's estimated initial state, whichever ``--initial`` the fit used."""
    from ..validation.edges import edge_lines, lti_edge_lines

    if hasattr(model, "frequency_response"):
        return lti_edge_lines(model, experiments)
    return edge_lines(experiments, simulated, model.outputs)


def _experiments(model, data, inputs, outputs, ts):
    """The records' columns for the model's channels, renamed to them; the sample time checked."""
    from ..data.sampling import PERIOD_RTOL, same_period, seconds

    ins = split_names(inputs, "--inputs") or tuple(model.inputs)
    outs = split_names(outputs, "--outputs") or tuple(model.outputs)
    for option, given, expected in (("--inputs", ins, model.inputs), ("--outputs", outs, model.outputs)):
        if len(given) != len(expected):
            raise click.UsageError(
                f"{option}: expected {len(expected)} names for the model's channels ({','.join(expected)}); "
                f"got {len(given)} ({','.join(given)})."
            )
    model_dt = getattr(model, "dt", None)
    experiments = read_experiments(data, ins, outs, ts, fallback_ts=model_dt)
    for exp in experiments:
        if model_dt is not None and not same_period(exp.dt, model_dt):
            raise DataError(
                f"record {exp.name} has sample time {seconds(exp.dt)} s; the model's is {seconds(model_dt)} s "
                f"(tolerance {PERIOD_RTOL:g} relative)."
            )
    return tuple(e.with_(input_names=tuple(model.inputs), output_names=tuple(model.outputs)) for e in experiments)


def _initial_conditions(model, experiments, initial: str):
    """Per record, :func:`~stageid.hysteresis.stage.validation.validate_record` (None for ``model``)."""
    if initial == "model":
        return None
    from ..hysteresis.stage.validation import validate_record

    return [validate_record(model, e.u[:, 0], e.y[:, 0], e.dt, initial) for e in experiments]


def _per_record(model, experiments, simulated) -> list[dict]:
    """Each record's own fit and tests (JSON form), the record's name under ``record``; a record
    too short for the tests gets its fit and the reason instead."""
    from ..validation.metrics import fit_percent, nrmse
    from ..validation.residuals import validate_model, validation_json

    out = []
    for exp, ys in zip(experiments, simulated):
        try:
            entry = validation_json(validate_model(model, [exp], MAX_LAG, ALPHA, simulated=[ys]))
        except DataError as exc:
            fits, errs = fit_percent(exp.y, ys), nrmse(exp.y, ys)
            entry = {
                "outputs": {
                    n: {"fit_percent": float(f), "nrmse": float(e)} for n, f, e in zip(model.outputs, fits, errs)
                },
                "untested": str(exc),
            }
        out.append({"record": exp.name, **entry})
    return out


def _hysteresis_metrics(summary: dict, experiments, result: dict) -> None:
    """Add ``max_error_percent`` and ``rms_error_percent`` (of the measured range) per output."""
    import numpy as np

    from ..hysteresis.metrics import max_error_percent, rms_error_percent

    y = np.vstack([e.y for e in experiments])
    ys = np.vstack(result["simulated"])
    for i, name in enumerate(summary["outputs"]):
        summary["outputs"][name]["max_error_percent"] = max_error_percent(y[:, i], ys[:, i])
        summary["outputs"][name]["rms_error_percent"] = rms_error_percent(y[:, i], ys[:, i])


def _write_report(folder: str, model, experiments, result: dict, summary: dict):
    """``index.html`` with the summary table, the ``resid`` figure per output, and hysteresis loops."""
    from ..plots.residuals import residual_figure
    from ..report import Report, write_report_folder

    report = Report("Model validation")
    from ..report.provenance import settings_section
    from ._common import command_line, command_settings

    settings_section(report, command_settings(), command_line())
    report.section("Summary")
    rows = [
        [name, o["fit_percent"], o["nrmse"], _verdict(o["whiteness"]), _verdict(o["independence"])]
        for name, o in summary["outputs"].items()
    ]
    report.table(["output", "fit [%]", "RMS error / range", "whiteness", "independence"], rows)
    report.section("Residual correlations")
    for name, entry in result["outputs"].items():
        fig = residual_figure(name, entry["whiteness"], entry["independence"])
        report.figure(
            fig,
            f"Residual of {name}: autocorrelation (lags 1..{MAX_LAG}) and cross-correlation with "
            f"each input (lags 0..{MAX_LAG}); shaded: per-lag {100 * (1 - ALPHA):g} % bound.",
        )
    if not hasattr(model, "frequency_response"):
        _loop_section(report, model, experiments, result)
    return write_report_folder(folder, report, summary)


def _loop_section(report, model, experiments, result: dict) -> None:
    """Measured and simulated loops beside the error in % of range; a long record of a fast input
    in a window of its last cycles beside the whole record's envelope."""
    import numpy as np

    from ..plots.hysteresis import loop_error_figure

    report.section("Hysteresis loops")
    for exp, ys in zip(experiments, result["simulated"]):
        for i, name in enumerate(model.outputs):
            y_range = float(np.ptp(exp.y[:, i]))
            unit = exp.output_units[i] or "output unit"
            labels = (f"{model.inputs[0]} [{exp.input_units[0] or 'input unit'}]", f"{name} [{unit}]")
            scale, error_label = (100.0 / y_range, "error [% of range]") if y_range > 0 else (1.0, f"error [{unit}]")
            fig = loop_error_figure(exp.time, exp.u[:, 0], exp.y[:, i], ys[:, i], labels, error_label, scale=scale)
            report.figure(fig, f"{exp.name}: {name} against {model.inputs[0]}, measured and simulated, and the error.")


def _verdict(test: dict) -> str:
    return "pass" if test["pass"] else "FAIL"


def _summary_text(summary: dict, names: list[str]) -> str:
    """One line per record and output, then (several records) one per output over all records."""
    if "records" not in summary:
        return _output_lines(summary, f"{names[0]}  ")
    lines = [_output_lines(r, f"{r['record']}  ") for r in summary["records"]]
    lines.append(_output_lines(summary, f"all {len(names)} records  "))
    return "\n".join(lines)


def _output_lines(summary: dict, prefix: str) -> str:
    if "untested" in summary:
        return "\n".join(
            f"{prefix}{name}: fit {o['fit_percent']:.2f} %  RMS error {100 * o['nrmse']:.3g} % of range  "
            f"(no residual tests: {summary['untested']})"
            for name, o in summary["outputs"].items()
        )
    lines = []
    for name, o in summary["outputs"].items():
        w, ind = o["whiteness"], o["independence"]
        line = (
            f"{prefix}{name}: fit {o['fit_percent']:.2f} %  RMS error {100 * o['nrmse']:.3g} % of range  "
            f"whiteness {_verdict(w)} (chi2 {w['statistic']:.1f}, limit {w['threshold']:.1f})  "
            f"independence {_verdict(ind)}"
        )
        for inp, t in ind["inputs"].items():
            line += f" [{inp}: chi2 {t['statistic']:.1f}, limit {t['threshold']:.1f}]"
        if o.get("untested_inputs"):
            line += f" [{', '.join(o['untested_inputs'])}: constant in the record, not tested]"
        if "max_error_percent" in o:
            line += f"  max error {o['max_error_percent']:.2f} % of range"
        lines.append(line)
    return "\n".join(lines)
