"""``stageid report``: an HTML report (figures embedded) of a model on the user's own data."""

from __future__ import annotations

from pathlib import Path

import click

from ._common import (
    MODEL_CHANNELS_HELP,
    channel_options,
    command_line,
    command_settings,
    read_experiments,
    say,
    split_names,
    trim_options,
)
from .outputs import check_output_folder


def write_report(model, experiments, out_dir: str, title: str | None = None, extra=None, uncertainty=None) -> Path:
    """Build the model report and write ``index.html`` and ``metrics.json`` into ``out_dir``.

    ``extra(report, metrics)``, when given, adds method-specific sections (the ``identify``
    verbs' ``--report`` uses it for uncertainty bands, selection plots, ...).  Nothing is
    written unless the whole report could be built: both files go to a temporary folder that
    is then moved into place (:func:`stageid.report.write_report_folder`).  ``uncertainty``
    (a FrequencyResponse with ``std``) puts +-2 std bands on the model's Bode plot.  The report
    opens with the command line and the running command's options.
    """
    from ..report import model_report, write_report_folder

    report, metrics = model_report(
        model, experiments, title, uncertainty=uncertainty, settings=command_settings(), command=command_line()
    )
    if extra is not None:
        extra(report, metrics)
    return write_report_folder(out_dir, report, metrics)


@click.command(
    "report",
    epilog="""
\b
Examples:
  stageid report model.json val.csv --inputs Z,Rx,Ry --outputs z,rx,ry --out report/
  stageid report hyst.json tri.csv --inputs V --outputs y --out hyst-report/
  stageid report frd.json --frf frf.csv --out report/   # the model beside a measured FRF
""",
)
@click.argument("model_path", metavar="MODEL.json", type=click.Path(dir_okay=False))
@click.argument("data", nargs=-1, type=click.Path(dir_okay=False))
@channel_options(*MODEL_CHANNELS_HELP)
@click.option("--title", default=None, help="Report title.")
@click.option(
    "--frf",
    "frf_path",
    default=None,
    type=click.Path(dir_okay=False),
    help="A measured frequency response (`stageid frf` / `freqresp` CSV or NPZ) drawn beside the model; "
    "its channels are the --inputs/--outputs names.",
)
@click.option(
    "--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Folder for index.html and metrics.json."
)
@trim_options
def report_command(
    model_path: str,
    data: tuple[str, ...],
    inputs: str | None,
    outputs: str | None,
    ts: float | None,
    title: str | None,
    frf_path: str | None,
    out_dir: str,
) -> None:
    """Report on MODEL.json: frequency response, poles and zeros, and simulation against DATA files."""
    from ..models import load_model

    check_output_folder(out_dir)
    model = load_model(model_path)
    ins = split_names(inputs, "--inputs") or tuple(model.inputs)
    outs = split_names(outputs, "--outputs") or tuple(model.outputs)
    # the data's columns are renamed to the model's channels, one for one: check the counts
    # here, where the message can say which side is which
    _check_count("--inputs", ins, "inputs", tuple(model.inputs))
    _check_count("--outputs", outs, "outputs", tuple(model.outputs))
    if ts is None and getattr(model, "dt", None) is not None:
        ts_used = None
    else:
        ts_used = ts
    experiments = read_experiments(data, ins, outs, ts_used) if data else ()
    if experiments:
        renamed = [e.with_(input_names=tuple(model.inputs), output_names=tuple(model.outputs)) for e in experiments]
        experiments = tuple(renamed)
    extra = None
    if frf_path is not None:
        frd = _read_frf(frf_path, model, ins, outs)

        def extra(report, metrics):
            from ..report.model_report import frf_section

            frf_section(report, metrics, model, frd, source=f"measured ({Path(frf_path).name})")

    path = write_report(model, experiments, out_dir, title, extra)
    say(f"report written to {path}")


def _read_frf(path: str, model, ins: tuple[str, ...], outs: tuple[str, ...]):
    """The FRF file's columns for the model's channels (named as in ``--inputs``/``--outputs``),
    in the model's order and renamed to its channels; an LTI model only."""
    from ..frf import FrequencyResponse, read_frd

    if not hasattr(model, "frequency_response"):
        raise click.UsageError(f"--frf needs a linear model with a frequency response; got a {type(model).__name__}.")
    frd = read_frd(path)
    missing = [n for n in ins if n not in frd.inputs] + [n for n in outs if n not in frd.outputs]
    if missing:
        raise click.UsageError(
            f"--frf '{path}' has no channel {missing[0]!r}; it has inputs {','.join(frd.inputs)} "
            f"and outputs {','.join(frd.outputs)}."
        )
    i = [frd.outputs.index(n) for n in outs]
    j = [frd.inputs.index(n) for n in ins]
    return FrequencyResponse(
        frd.freqs,
        frd.response[:, i][:, :, j],
        None if frd.std is None else frd.std[:, i][:, :, j],
        None if frd.coherence is None else frd.coherence[:, i],
        tuple(model.inputs),
        tuple(model.outputs),
        None if frd.total_std is None else frd.total_std[:, i][:, :, j],
    )


def _check_count(option: str, given: tuple[str, ...], side: str, model_names: tuple[str, ...]) -> None:
    """Refuse a renaming list whose length differs from the model's channels on ``side``.

    Example message: ``--inputs: expected 3 names for the model's inputs (a,b,c); got 2 (x,y).``
    """
    if len(given) != len(model_names):
        raise click.UsageError(
            f"{option}: expected {len(model_names)} name{'s' if len(model_names) != 1 else ''} for the model's {side} "
            f"({','.join(model_names)}); got {len(given)} ({','.join(given)})."
        )
