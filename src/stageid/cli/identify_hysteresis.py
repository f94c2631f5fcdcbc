"""``stageid identify hysteresis``: identify a classical or modified PI model from records."""

from __future__ import annotations

from pathlib import Path

import click

from .._errors import DataError
from ._common import say, trim_options
from .outputs import check_output, check_output_folder, write_model_output


def _time_constants(ctx: click.Context, param: click.Parameter, value: str | None) -> tuple[float, ...] | str | None:
    if value is None:
        return None
    if value in ("auto", "none"):
        return value
    try:
        taus = tuple(float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(
            f"expected comma-separated positive seconds (e.g. 0.05,0.5,5), auto or none; got {value!r}."
        ) from None
    if not taus or not all(t > 0 and t < float("inf") for t in taus):
        raise click.BadParameter(
            f"expected comma-separated positive seconds (e.g. 0.05,0.5,5), auto or none; got {value!r}."
        )
    return taus


def _order(ctx: click.Context, param: click.Parameter, value: str | None) -> int | str | None:
    if value is None or value in ("auto", "none"):
        return value
    try:
        order = int(value)
    except ValueError:
        order = -1
    if order < 0:
        raise click.BadParameter(f"expected an integer order >= 0, auto or none; got {value!r}.")
    return order


@click.command(
    "hysteresis",
    epilog="""
\b
Examples:
  stageid identify hysteresis decay.csv --input V --output y --model modified-pi -o hyst.json
  stageid identify hysteresis forc.csv --input V --output y --model pi --operators 20 -o pi.json
  stageid identify hysteresis a.csv b.csv --input V --output y --model modified-pi -o hyst.json
  stageid identify hysteresis forc.csv --input V --output y --creep 0.05,0.2,1,5,20 -o hyst.json
  stageid identify hysteresis f20.csv f100.csv --input V --output y --dynamics auto --creep auto -o stage.json
  stageid identify hysteresis f20.csv f100.csv --input V --output y --model preisach --dynamics auto --creep auto -o stage.json
  stageid identify hysteresis 20_hz_no_lp.mat --input "Y(3).Data" --output "Y(1).Data" --start 0.053 -o hyst.json
""",
)
@click.argument("data", nargs=-1, required=True, metavar="DATA...", type=click.Path(dir_okay=False))
@click.option("--input", "input_name", required=True, help="Input column of the records (drive, e.g. V).")
@click.option(
    "--output",
    "output_name",
    required=True,
    help="Output column of the records (displacement, e.g. y); the model file is -o/--output-file.",
)
@click.option(
    "--model",
    "kind",
    type=click.Choice(["pi", "modified-pi", "preisach"]),
    default="modified-pi",
    show_default=True,
    help="Classical PI (plays), the letter's modified PI (coupled plays), or a discrete Preisach "
    "model (uniform-density cells on a triangular grid, --levels; with --creep/--dynamics it is "
    "the hysteresis of a stage model; `stageid compensate` inverts it exactly).",
)
@click.option(
    "--levels",
    "n_levels",
    type=click.IntRange(min=2),
    default=20,
    show_default=True,
    help="Preisach only: cells per axis of the grid over the input range (n(n+1)/2 weights); "
    "cells the records leave undetermined are filled by a smoothness prior (the summary says how many).",
)
@click.option(
    "--operators",
    "n_operators",
    type=click.IntRange(min=2),
    default=20,
    show_default=True,
    help="Number of operators (thresholds equally spaced over the input range, the first is 0); "
    "at most 1000 (pi) or 100 (modified-pi), one per 5 samples of the records and the "
    "number of distinct input values.",
)
@click.option(
    "--initial-state",
    type=click.Choice(["auto", "zero", "ascending", "descending"]),
    default="auto",
    show_default=True,
    help="Operator state at the first sample of each record.",
)
@click.option(
    "--input-warp/--no-input-warp",
    default=True,
    show_default=True,
    help="Modified PI only: also fit a monotone quadratic input warp (our extension); "
    "--no-input-warp gives the letter's model exactly.",
)
@click.option(
    "--creep",
    "creep",
    default=None,
    callback=_time_constants,
    metavar="TAU1,TAU2,...",
    help="Also fit a linear creep term: first-order lags of the input with these time constants "
    "[s], weights >= 0 (our extension; the records' time column gives dt); auto: picked by "
    "held-out error (writes a stage model); none: no creep.",
)
@click.option(
    "--dynamics",
    "dynamics",
    default=None,
    callback=_order,
    metavar="N|auto|none",
    help="Fit a stage model: hysteresis -> creep -> discrete linear dynamics of order N with unit DC "
    "gain, identified jointly (auto: order 0-4 by held-out error on the records; 0: a stage model without "
    "dynamics, as auto's order 0; none: no dynamics; "
    "an order N that does not lower the held-out error is dropped, and the summary says so). "
    "Writes a model of kind `stage`; needs a time axis.",
)
@click.option(
    "--disturbance-modes",
    "modes",
    type=click.Choice(["auto", "spectrum", "none"]),
    default="auto",
    show_default=True,
    help="With --dynamics: the lightly damped modes that a broadband disturbance rings in every "
    "record's residual (drive harmonics left out) go into the dynamics, with unit DC gain, and the "
    "model is refitted; auto keeps them when they lower the held-out one-step prediction error "
    "(each record left out in turn; a noise model with the modes' poles), spectrum whenever they "
    "are found; none: never. "
    "The summary and the JSON list the modes taken.",
)
@click.option("--ts", type=float, default=None, help="Sample time [s] for files without a `t` column.")
@click.option(
    "-o",
    "--output-file",
    "out",
    default=None,
    type=click.Path(dir_okay=False),
    help="Model file to write (JSON; required); --output names the output column.",
)
@click.option("--quiet", is_flag=True, help="Do not print the fit summary, nor a stage fit's progress on stderr.")
@click.option(
    "--report",
    "report_dir",
    default=None,
    type=click.Path(file_okay=False),
    help="Also write an HTML report (measured vs modelled loops, error traces) into this folder.",
)
@trim_options
def identify(
    data: tuple[str, ...],
    input_name: str,
    output_name: str,
    kind: str,
    n_operators: int,
    initial_state: str,
    input_warp: bool,
    ts: float | None,
    out: str,
    quiet: bool,
    report_dir: str | None,
    creep: tuple[float, ...] | str | None = None,
    dynamics: int | str | None = None,
    n_levels: int = 20,
    modes: str = "auto",
) -> None:
    """Identify a PI, modified-PI or Preisach hysteresis model from one or more DATA records.

    Each record gets its own output offset (sensor zero) and starting state; the model keeps
    the first record's offset and starts from the zero state at 0 input. Prints the max and
    RMS error of the fit in % of each record's output range.

    With --dynamics (or --creep auto) the model is a rate-dependent stage (kind `stage`):
    hysteresis -> creep -> discrete dynamics with unit DC gain, identified jointly; records at
    several rates are the normal input.
    """
    from ..hysteresis import PIIdentifier

    # a bad -o or --report is refused before the records are read or any model is fitted
    out = _model_file(out, output_name)
    check_output(out, "model")
    if report_dir is not None:
        check_output_folder(report_dir)
    exps = _read_records(data, input_name, output_name, ts)
    rate_independent = creep in (None, "none") and dynamics in (None, "none")
    if kind == "preisach" and rate_independent:
        from ..hysteresis import PreisachIdentifier

        fit = PreisachIdentifier(n_levels=n_levels).fit(list(exps))
    elif dynamics is None and creep != "auto":  # today's rate-independent (or fixed-creep) model
        fit = PIIdentifier(
            kind,
            n_operators=n_operators,
            initial_state=initial_state,
            input_warp=input_warp,
            creep=None if creep == "none" else creep,
            # a report draws the band the weights' uncertainty puts on the loops
            weight_uncertainty="auto" if report_dir is not None else "none",
        ).fit(list(exps))
    else:
        settings = (kind, n_operators, initial_state, input_warp, creep, dynamics, n_levels, modes)
        fit = _identify_stage(exps, *settings, quiet=quiet)
    write_model_output(out, fit.model)
    if not quiet:
        say(fit.summary())
    if report_dir is not None:
        from .report import write_report

        def extra(report, metrics):
            from ..report.stage_report import fit_summary_section

            fit_summary_section(report, fit, [e.name or f"record {k}" for k, e in enumerate(exps)])
            if getattr(fit, "held_out", ()):  # the summary shows the best few; the report all of them
                _candidate_table(report, fit)

        # the model starts from the zero state at 0 input with the first record's offset; other
        # records' sensor zeros differ, so each is shown against the model shifted to its fitted offset
        records = [
            e.with_(
                y=e.y - (off - fit.output_offsets[0]),
                input_names=tuple(fit.model.inputs),
                output_names=tuple(fit.model.outputs),
            )
            for e, off in zip(exps, fit.output_offsets)
        ]
        band = getattr(fit, "weight_uncertainty", None)
        path = write_report(fit.model, records, report_dir, "Hysteresis identification", extra, uncertainty=band)
        say(f"report written to {path}")


def _candidate_table(report, fit) -> None:
    """Every held-out candidate of a stage fit, best first, as a table of the report."""
    rows = [
        (n, ", ".join(f"{t:g}" for t in taus) or "none", score, "chosen" if (n, tuple(taus)) == fit.chosen else "")
        for n, taus, score in sorted(fit.held_out, key=lambda c: c[2])
    ]
    header = ("dynamics order", "creep time constants [s]", "held-out RMS [% of range]", "")
    report.section("Held-out candidates")
    report.table(header, rows, "Every candidate, best first (RMS summed over the records left out)")


def _read_records(data, input_name: str, output_name: str, ts: float | None):
    """The records' input and output columns; a file name given to --output is explained."""
    from ._common import read_experiments

    try:
        return read_experiments(list(data), [input_name], [output_name], ts)
    except DataError as exc:
        if not _file_like(output_name) or output_name not in str(exc):
            raise
        raise DataError(f"{exc} (--output names the output column; the model file is -o/--output-file.)") from None


def _file_like(name: str) -> bool:
    return Path(name).suffix.lower() in (".json", ".csv", ".npz", ".mat")


def _model_file(out: str | None, output_name: str) -> str:
    """The -o file; its absence is explained when --output was given a file name instead."""
    if out is not None:
        return out
    hint = (
        f"; --output names the output column (e.g. y), and '{output_name}' looks like the model file: give it with -o"
        if _file_like(output_name)
        else ""
    )
    raise click.UsageError(f"Missing option '-o' / '--output-file' (the model file to write){hint}.")


def _identify_stage(
    exps, kind, n_operators, initial_state, input_warp, creep, dynamics, n_levels, modes="auto", quiet=False
):
    """The stage model (hysteresis -> creep -> dynamics); the records' time axis gives dt.
    A Preisach model holds no creep term of its own, so any --creep makes it a stage.
    Its progress goes to stderr (a search over candidates takes minutes) unless ``quiet``."""
    from ..hysteresis.stage.identification import StageIdentifier
    from .progress import StepProgress

    progress = None if quiet else StepProgress()
    try:
        return StageIdentifier(
            kind,
            n_operators=n_operators,
            dynamics=None if dynamics == "none" else dynamics,
            creep=None if creep == "none" else creep,
            initial_state=initial_state,
            input_warp=input_warp,
            n_levels=n_levels,
            disturbance_modes=None if modes == "none" else modes,
        ).fit(list(exps), progress=progress)
    finally:
        if progress is not None:
            progress.close()
