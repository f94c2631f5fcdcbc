"""``stageid identify closedloop ... --controller unknown``: the plant from closed-loop records alone.

The routes of :mod:`stageid.closedloop.direct`, :mod:`~stageid.closedloop.two_stage` and
:mod:`~stageid.closedloop.joint`, chosen by ``--method``; the command that parses the options
is :mod:`stageid.cli.identify_closedloop`, which hands over here when the controller is unknown.
"""

from __future__ import annotations

from dataclasses import dataclass

import click

from .._errors import IdentificationError, ModelError
from ._common import say, split_names
from .outputs import write_model_output

__all__ = ["UNKNOWN_METHODS", "UnknownRequest", "run_unknown", "known_controller_method"]

UNKNOWN_METHODS = ("direct", "two-stage", "joint")
KNOWN_METHODS = ("oe", "armax", "bj", "arx")


def known_controller_method(method: str | None, references: str | None) -> str:
    """The known-controller route's ``--method`` (default oe), refusing the unknown-controller ones."""
    if method in UNKNOWN_METHODS:
        raise click.UsageError(
            f"--method {method} is for --controller unknown; a known controller takes {', '.join(KNOWN_METHODS)}."
        )
    if references is None:
        raise click.UsageError("a known controller needs --references R1,R2[,R3] (one excited per file).")
    return method or "oe"


@dataclass(frozen=True)
class UnknownRequest:
    """The options of one ``--controller unknown`` run, as the command line gave them."""

    experiments: tuple[str, ...]
    references: str | None
    outputs: str
    plant_inputs: str | None
    ts: float | None
    band: tuple[float, float]
    method: str | None
    order: str
    discrete: bool
    output: str
    report_dir: str | None
    loop_output: str | None


def _parse_order(text: str) -> int | str:
    if text == "auto":
        return "auto"
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise click.UsageError(f"--order must be 'auto' or an integer >= 1; got {text!r}.")
    return n


def _estimator(method: str, order: int | str, refs: tuple[str, ...] | None):
    from ..closedloop import DirectPredictionError, JointInputOutput, TwoStageProjection

    names = list(refs) if refs else None
    if method == "direct":
        return DirectPredictionError(order=order, references=names)
    if not refs:
        raise click.UsageError(f"--method {method} needs the recorded references: --reference R1[,R2].")
    if method == "two-stage":
        return TwoStageProjection(order=order, references=names)
    return JointInputOutput(order=order, references=names)


def run_unknown(req: UnknownRequest, uncertainty) -> None:
    """Read the records, fit the chosen route, write the plant (and the uncertainty table, report)."""
    from ..data import as_experiments
    from ._common import read_table_checked

    if req.method in KNOWN_METHODS:
        raise click.UsageError(
            f"--method {req.method} needs a known controller; with --controller unknown use {', '.join(UNKNOWN_METHODS)}."
        )
    if req.loop_output is not None:
        raise click.UsageError("--closed-loop-output needs a known controller (no closed loop is identified).")
    method = req.method or "direct"

    refs = split_names(req.references, "--reference")
    outs = split_names(req.outputs, "--outputs")
    ins = split_names(req.plant_inputs, "--plant-inputs")
    if ins is None:
        raise click.UsageError("--controller unknown needs the plant-input columns: --plant-inputs U1[,U2].")
    assert outs is not None
    order = _parse_order(req.order)
    est = _estimator(method, order, refs)
    if uncertainty.wanted and method == "joint":
        raise click.UsageError("the joint route gives no bands: --uncertainty needs --method direct or two-stage.")
    tables = [read_table_checked(path, req.ts) for path in req.experiments]
    inputs = list(refs or ()) + list(ins)
    exps = as_experiments(
        [t.experiment(inputs=inputs, outputs=list(outs), name=str(p)) for t, p in zip(tables, req.experiments)]
    )
    uncertainty.check_nyquist(exps[0].dt)
    result = est.fit(exps)
    plant = result.model
    if not req.discrete:
        try:
            plant = plant.d2c("zoh")
        except ModelError as exc:
            raise IdentificationError(
                f"the plant has no continuous equivalent ({exc}); write it at the sample time with --discrete."
            ) from None
    write_model_output(req.output, plant)
    line = uncertainty.write(result, req.band, exps[0].dt)
    say(result.summary(), err=True)
    if line:
        say(line, err=True)
    if req.report_dir is not None:
        _write_report(result, req.band, req.report_dir)


def _write_report(result, band: tuple[float, float], report_dir: str) -> None:
    """Report: the summary (assumptions and checks) and, where the route gives them, the bands."""
    import numpy as np

    from ..report import Report, uncertainty_section, write_report_folder

    report = Report("Closed-loop identification without the controller")
    from ..report.provenance import settings_section
    from ._common import command_line, command_settings

    settings_section(report, command_settings(), command_line())
    metrics = {
        "method": result.method,
        "unstable_poles_rad_s": [float(p.real) for p in result.unstable_poles],
        "checks_passed": {c.name: bool(c.passed) for c in result.checks},
    }
    report.section("Identified plant")
    report.paragraph(result.summary())
    if result.parameter_covariance is not None:
        lo = band[0] if band[0] > 0 else 1e-3 * band[1]
        f = np.geomspace(lo, min(band[1], 0.5 / result.dt), 200)
        uncertainty_section(report, metrics, result.response_uncertainty(f), "identified plant", level=3)
    path = write_report_folder(report_dir, report, metrics)
    say(f"report written to {path}", err=True)
