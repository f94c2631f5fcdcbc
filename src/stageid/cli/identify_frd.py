"""``stageid identify frd``: a state-space model fitted to a measured frequency response."""

from __future__ import annotations

from typing import Any

import click

from .._errors import StageIdError
from ._common import command_line, say
from .flags import as_flags
from .outputs import check_output, check_output_folder, output_option, write_model_output
from .uncertainty import UncertaintyRequest, uncertainty_options

#: The fit's parameters as this command's options (its band's upper end is what a user lowers).
_OPTIONS = {"sample_time": "dt", "band": "fmax"}


def _order_or_auto(text: str, option: str) -> int | str:
    if text == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise click.BadParameter(f"must be an integer or 'auto'; got {text!r}.", param_hint=option) from None


@click.command(
    "frd",
    epilog="""
\b
Examples:
  stageid identify frd frf.csv --order 6 --dt 0.0002 -o model.json
  stageid identify frd frf.npz --order auto --continuous --fmax 2000 -o model.json
  stageid identify frd afm.csv --order 16 --dt 4e-5 --fmin 1 --fmax 2000 --delay auto --report rep/ -o afm.json
  stageid identify frd frf.csv --order 6 --dt 0.0002 -o model.json --uncertainty bands.csv
  stageid identify frd FRF_data_current_stage2.mat --response G_uz2stage --order 8 --dt 4e-5 --fmax 2000 -o afm.json
""",
)
@click.argument("frf_path", metavar="FRF.(csv|npz|mat)", type=click.Path(dir_okay=False))
@click.option(
    "--response",
    default=None,
    help="The complex response vector of a .mat FRF to fit (e.g. G_uz2stage or frf.G_uz2stage), "
    "when the file holds several.",
)
@click.option(
    "--order", default="auto", show_default=True, help="States of the model, or 'auto' (held-out frequencies)."
)
@click.option("--dt", type=float, default=None, help="Sample time [s] of a discrete model.")
@click.option("--continuous", is_flag=True, help="Fit a continuous-time model (dt: null).")
@click.option("--fmin", type=float, default=None, help="Lowest frequency fitted [Hz].")
@click.option("--fmax", type=float, default=None, help="Highest frequency fitted [Hz].")
@click.option(
    "--weight",
    type=click.Choice(["auto", "none", "std", "coherence"]),
    default="auto",
    show_default=True,
    help="Weights of the output-error fit: 1/std^2 (the total std of a BLA when present, else the noise std), "
    "coherence, or none (auto: std when present).",
)
@click.option("--delay", default="0", show_default=True, help="Input delay in samples, or 'auto' (discrete only).")
@click.option(
    "--report", "report_dir", default=None, type=click.Path(file_okay=False), help="Folder for an HTML report."
)
@output_option("Model .json.")
@uncertainty_options
def frd_command(
    frf_path: str,
    response: str | None,
    order: str,
    dt: float | None,
    continuous: bool,
    fmin: float | None,
    fmax: float | None,
    weight: str,
    delay: str,
    report_dir: str | None,
    output: str,
    uncertainty_file: str | None,
    uncertainty_grid: str | None,
) -> None:
    """Fit a MIMO state-space model to FRF (columns f_hz, re_/im_<out>_<in>, optional std_, coh_).

    Frequency-domain subspace realisation, then a weighted output-error refinement on the
    complex response, stability enforced.  Channel names come from the columns.  A MATLAB
    .mat FRF (complex vectors beside a frequency vector, structs included) gives one SISO
    response, chosen with --response when the file holds several.
    """
    check_output(output, "model")
    if report_dir is not None:
        check_output_folder(report_dir)
    uncertainty = UncertaintyRequest(uncertainty_file, uncertainty_grid)
    if dt is None and not continuous:
        raise click.UsageError("give --dt S for a discrete model or --continuous for a continuous one.")
    if dt is not None and continuous:
        raise click.UsageError("give either --dt or --continuous, not both.")
    uncertainty.check_nyquist(dt)
    from ..frf import read_frd

    estimator = _estimator(order, dt, fmin, fmax, weight, delay)
    frd = read_frd(frf_path, response)
    try:
        result = estimator.fit(frd)
    except StageIdError as exc:
        raise type(exc)(as_flags(str(exc), _OPTIONS)) from None
    write_model_output(output, result.model)
    uncertainty_line = uncertainty.write(result, result.band, result.model.dt)
    if report_dir is not None:
        from ..report import write_report_folder
        from ..report.frd_report import frd_fit_report

        settings = {"FRF file": frf_path, "order": _asked(result.order, order)}
        settings |= {"delay [samples]": _asked(result.delay, delay), "weight": _asked(result.weight, weight)}
        settings |= {
            "band fitted [Hz]": result.band,
            "model": "continuous" if dt is None else f"discrete, Ts = {dt:g} s",
        }
        write_report_folder(report_dir, *frd_fit_report(frd, result, settings, command_line()))
    from ..report.provenance import percent_text

    errors = ", ".join(f"{name} {percent_text(e)} %" for name, e in zip(result.model.inputs, result.column_errors))
    say(
        f"order {result.order}, delay {result.delay} samples, weight {_WEIGHT_WORDS.get(result.weight, result.weight)}; "
        f"max error per input column (of its peak): {errors}"
    )
    say(f"model written to {output}")
    if uncertainty_line:
        say(uncertainty_line)


def _estimator(order: str, dt: float | None, fmin: float | None, fmax: float | None, weight: str, delay: str) -> Any:
    """The fit the options ask for (a band end above Nyquist refused in the options' words)."""
    from ..frf import FRDIdentification

    if dt is not None and fmax is not None and fmax > 0.5 / dt * (1 + 1e-12):
        raise click.BadParameter(
            f"must be at most the Nyquist frequency {0.5 / dt:g} Hz of --dt; got {fmax:g}.", param_hint="--fmax"
        )
    return FRDIdentification(
        order=_order_or_auto(order, "--order"),
        sample_time=dt,
        band=None if fmin is None and fmax is None else (fmin, fmax),
        weight=weight,
        delay=_order_or_auto(delay, "--delay"),
    )


#: How the summary names the weightings whose source matters to the user.
_WEIGHT_WORDS = {
    "total-std": "1/total variance (noise + nonlinear distortion, stdtot_ columns)",
    "std": "1/noise variance (std_ columns)",
}


def _asked(used: object, given: str) -> str:
    """A setting as used, saying when ``auto`` chose it (``16 (auto)``)."""
    return f"{used} (auto)" if given == "auto" else str(used)
