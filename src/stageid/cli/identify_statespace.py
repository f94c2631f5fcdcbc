"""``stageid identify statespace``: open-loop MIMO state space by Hankel-Toeplitz MAP (Cao & Chen)."""

from __future__ import annotations

import click

from ._common import channel_options, parse_band, read_experiments, say, split_names, trim_options
from .chunked_input import chunked_record, fit_on_chunks, scheduler_option
from .outputs import check_output, check_output_folder, output_option, write_model_output
from .uncertainty import UncertaintyRequest, uncertainty_options


def _int_or_auto(text: str, option: str, allow_list: bool = False) -> int | str | list[int]:
    t = text.strip().lower()
    if t == "auto":
        return "auto"
    try:
        values = [int(v) for v in t.split(",")] if allow_list else [int(t)]
    except ValueError:
        raise click.UsageError(
            f"{option} must be a positive integer{' (or a comma list)' if allow_list else ''} or 'auto'; got {text!r}."
        ) from None
    if any(v < 1 for v in values):
        raise click.UsageError(f"{option} must be positive; got {text!r}.")
    return values if len(values) > 1 else values[0]


@click.command(
    "statespace",
    epilog="""
\b
Examples:
  stageid identify statespace exp.csv --inputs Z,Rx,Ry --outputs z,rx,ry --order 15 -o model.json
  stageid identify statespace cz.csv crx.csv cry.csv --inputs Z,Rx,Ry --outputs z,rx,ry \\
      --per-channel --order 7,4,4 -o model.json   # one file per excited input
  stageid identify statespace run.npz --inputs u1,u2 --outputs y1,y2 --ts 0.002 -o model.json
  stageid identify statespace exp.csv --inputs Z,Rx,Ry --outputs z,rx,ry --order 15 -o model.json \\
      --uncertainty bands.csv --uncertainty-grid 1:100:200   # response, std
""",
)
@click.argument("data", nargs=-1, required=True, type=click.Path())
@channel_options(
    "Input columns A,B,C.",
    "Output columns X,Y,Z.",
    "Sample time in s when the files have no 't' column.",
    required=True,
)
@click.option(
    "--order",
    "order_text",
    default="auto",
    show_default=True,
    help="Model order N, 'auto' (held-out simulation error), or one per input with --per-channel (7,4,4).",
)
@click.option(
    "--horizon",
    "horizon_text",
    default="auto",
    show_default=True,
    help="Horizon p of the Hankel-Toeplitz model, or 'auto' (held-out prediction error).",
)
@click.option(
    "--method",
    type=click.Choice(["map", "ls"]),
    default="map",
    show_default=True,
    help="MAP with a weak prior (eq. 17) or batch least squares (identified Hankel matrix).",
)
@click.option(
    "--per-channel", is_flag=True, help="One single-input model per input from the files that move only it, stacked."
)
@click.option(
    "--forgetting", type=float, default=1.0, show_default=True, help="Exponential forgetting factor in (0, 1]."
)
@click.option(
    "--realization",
    type=click.Choice(["frequency", "markov"]),
    default="frequency",
    show_default=True,
    help="frequency: in-band realisation (robust to band-limited data); markov: Lemma 1 on Markov parameters.",
)
@click.option(
    "--band", "band_text", default=None, help="Band FMIN:FMAX in Hz for the realisation (default: the excited band)."
)
@output_option("Model file (stageid.lti/1).")
@click.option(
    "--report",
    "report_dir",
    default=None,
    type=click.Path(file_okay=False),
    help="Also write an HTML report (Bode with posterior bands, selection plots, simulation fits) into this folder.",
)
@uncertainty_options
@scheduler_option
@trim_options
def statespace_command(
    data: tuple[str, ...],
    inputs: str,
    outputs: str,
    ts: float | None,
    order_text: str,
    horizon_text: str,
    method: str,
    per_channel: bool,
    forgetting: float,
    realization: str,
    band_text: str | None,
    output: str,
    report_dir: str | None,
    uncertainty_file: str | None,
    uncertainty_grid: str | None,
    scheduler: str | None,
) -> None:
    """Identify a discrete MIMO state-space model from open-loop records (Cao & Chen 2013).

    Several DATA files are several records of the same stage (e.g. one per excited input).
    Writes the model with the data's channel names; prints a summary on stderr.
    """
    from ..subspace.estimator import HankelMAP

    # a bad -o or --report is refused before the records are read or any model is fitted
    check_output(output, "model")
    if report_dir is not None:
        check_output_folder(report_dir)
    uncertainty = UncertaintyRequest(uncertainty_file, uncertainty_grid)
    ins = split_names(inputs, "--inputs")
    outs = split_names(outputs, "--outputs")
    assert ins is not None and outs is not None
    order = _int_or_auto(order_text, "--order", allow_list=True)
    horizon = _int_or_auto(horizon_text, "--horizon")
    if isinstance(horizon, list):
        raise click.UsageError(f"--horizon must be one integer or 'auto'; got {horizon_text!r}.")
    band = None if band_text is None else parse_band(band_text)
    record = chunked_record(data, ins, outs, ts, "--report" if report_dir is not None else "", scheduler)
    exps = read_experiments(data, ins, outs, ts) if record is None else None
    uncertainty.check_nyquist(exps[0].dt if record is None else record.dt)
    est = HankelMAP(
        horizon=horizon,
        order=order,
        method=method,
        per_channel=per_channel,
        forgetting=forgetting,
        realization=realization,
        band=band,
    )
    # warnings become one-line messages printed after success (cli.main); a chunked record is
    # fitted from statistics computed chunk by chunk, here or on --scheduler
    result = est.fit(exps) if record is None else fit_on_chunks(est, record, scheduler)
    write_model_output(output, result.model)  # committed with the report, after both succeeded
    fit_band = identified_band(result)
    uncertainty_line = uncertainty.write(result, fit_band, result.model.dt)
    say(result.summary())
    if exps is not None:
        from ..validation.edges import lti_edge_lines

        for line in lti_edge_lines(result.model, exps):
            say(line)
    if uncertainty_line:
        say(uncertainty_line)
    if report_dir is not None:
        _write_report(result, exps, report_dir, fit_band)


def _write_report(result, exps, report_dir: str, fit_band: tuple[float, float]) -> None:
    """The model report with the realised model's +-2 std bands, the eq. 9 bands and the selection plots."""
    import numpy as np

    from ..plots.subspace import bode_with_bands, selection_plot
    from .report import write_report

    lo, hi = fit_band
    f = np.geomspace(max(lo, 1e-3), hi, 300)

    # a chunked record comes without experiments: its units are then not known here
    units = {"input_units": exps[0].input_units, "output_units": exps[0].output_units} if exps else {}

    def extra(report, metrics):
        report.section("Hankel-MAP diagnostics")
        report.paragraph(result.summary())
        report.figure(
            bode_with_bands(result, f, **units),
            "Response of the Hankel-Toeplitz model (eq. 9) with +-2 std posterior bands, and the realised model.",
        )
        for ch in result.channels:
            for table in (ch.horizon_table, ch.order_table):
                if table is not None:
                    report.figure(
                        selection_plot(table, title=f"{', '.join(ch.inputs)}: held-out error vs {table.kind}"),
                        f"Selection of the {table.kind} by held-out error for input(s) {', '.join(ch.inputs)}.",
                    )

    bands = result.response_uncertainty(np.geomspace(lo if lo > 0 else 1e-3 * hi, hi, 300))
    path = write_report(result.model, exps, report_dir, "Hankel-MAP identification", extra, uncertainty=bands)
    say(f"report written to {path}")


def identified_band(result) -> tuple[float, float]:
    """The band the model was identified on: the channels' bands together (Hz)."""
    bands = [ch.band for ch in result.channels]
    return min(b[0] for b in bands), max(b[1] for b in bands)
