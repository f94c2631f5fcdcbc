"""``stageid frf``: a frequency response (with coherence and uncertainty) from measured records."""

from __future__ import annotations

import click

from ._common import channel_options, read_experiments, say, split_names, trim_options
from .chunked_input import chunked_record, scheduler_option, statistics_client
from .outputs import check_output, output_option, write_table_output


@click.command(
    "frf",
    epilog="""
\b
Examples:
  stageid frf noise.csv --inputs u --outputs y -o frf.csv
  stageid frf ex1.npz ex2.npz --inputs Z,Rx --outputs z,rx --segment 4096 -o frf.npz
  stageid frf run.csv --inputs u --outputs y --method lpm -o frf.npz
  stageid frf ms.csv --inputs u --outputs y --method periodic --periods 8 --transient-periods 2 -o frf.csv
  stageid frf ms_r*.csv --inputs V --outputs z --method bla --design ms.multisine.json -o bla.csv
""",
)
@click.argument("data", nargs=-1, required=True, type=click.Path())
@channel_options("Input columns, comma-separated.", "Output columns, comma-separated.", required=True)
@click.option(
    "--method",
    type=click.Choice(["welch", "lpm", "periodic", "bla"]),
    default="welch",
    show_default=True,
    help="welch: H1 over segments; lpm: local polynomial method; periodic: average over periods; "
    "bla: best linear approximation over random-phase realisations (one file each, or one per experiment).",
)
@click.option("--segment", type=int, default=None, help="welch: samples per segment (default: chosen and printed).")
@click.option("--overlap", type=float, default=None, help="welch: overlap fraction of segments [0, 1) (default 0.5).")
@click.option("--window", default=None, help="welch: scipy window name (default hann).")
@click.option(
    "--periods",
    type=int,
    default=None,
    help="periodic: whole periods in each record (required); bla: detected if not given.",
)
@click.option(
    "--transient-periods",
    type=int,
    default=None,
    help="periodic: leading periods dropped (default 1); bla: detected from the outputs if not given.",
)
@click.option(
    "--transient",
    type=click.Choice(["drop", "lpm"]),
    default=None,
    help="bla: drop the transient periods (default), or keep every period and remove the transient by the "
    "local polynomial method (records that never settle, or of only 2 periods).",
)
@click.option(
    "--design",
    "design_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="bla: the .multisine.json of `stageid signal multisine` (periods, lines, experiments per realisation).",
)
@output_option("Output .csv or .npz (by extension).")
@scheduler_option
@trim_options
def frf_command(
    data: tuple[str, ...],
    inputs: str,
    outputs: str,
    ts: float | None,
    method: str,
    segment: int | None,
    overlap: float | None,
    window: str | None,
    periods: int | None,
    transient_periods: int | None,
    transient: str | None,
    design_path: str | None,
    output: str,
    scheduler: str | None,
) -> None:
    """Estimate the frequency response from DATA files (one per excited input, or several at once).

    Columns written: `f_hz`, `re_<out>_<in>`, `im_<out>_<in>`, `std_<out>_<in>`
    (sqrt(E|H_est - H|^2)) for every pair, and `coh_<out>` (multiple coherence) per output.
    Welch's defaults equal scipy.signal.csd(window="hann", nperseg=N, noverlap=N//2).
    bla adds `stdtot_` (noise and stochastic nonlinear distortion), `stdnl_` (distortion alone)
    and, with detection lines, `stdodd_` / `stdeven_` per pair (see docs/guide/bla.md).
    """
    check_output(output, "table")
    _check_method_options(method, segment, overlap, window, periods, transient_periods)
    for name, value in (("--design", design_path), ("--transient", transient)):
        if value is not None and method != "bla":
            raise click.UsageError(f"{name} applies to --method bla; got --method {method}.")
    ins = split_names(inputs, "--inputs")
    outs = split_names(outputs, "--outputs")
    if method == "bla":  # reads realisation by realisation, memory-mapped: no chunked path needed
        from .bla import bla_command

        bla_command(data, ins, outs, ts, (periods, transient_periods, transient), design_path, scheduler, output)
        return
    # a record larger than memory: Welch's spectra chunk by chunk (lpm and periodic refuse it)
    record = chunked_record(data, ins, outs, ts, "" if method == "welch" else f"--method {method}", scheduler)
    if method == "welch":
        from ..frf.welch import cross_spectra, default_segment, h1_from_spectra

        exps = _read_records(data, ins, outs, ts) if record is None else [record]
        if segment is None:
            segment = default_segment(min(e.n_samples for e in exps))
            chosen = " (chosen from the record; set it with --segment)"
        else:
            chosen = ""
        if record is not None:
            from ..frf.welch_chunked import chunked_cross_spectra

            with statistics_client(scheduler) as client:
                spectra = chunked_cross_spectra(
                    record, segment, 0.5 if overlap is None else overlap, window or "hann", client=client
                )
        else:
            spectra = cross_spectra(exps, segment, 0.5 if overlap is None else overlap, window or "hann")
        frd = h1_from_spectra(spectra, ins, outs)
        say(f"welch: segment {segment} samples{chosen}, {spectra.n_segments} segments, resolution {frd.freqs[0]:g} Hz")
    elif method == "lpm":
        import numpy as np

        from ..frf.lpm import lpm_frf

        frd = lpm_frf(read_experiments(data, ins, outs, ts))
        spacing = float(np.min(np.diff(frd.freqs))) if frd.n_freqs > 1 else float(frd.freqs[0])
        say(f"lpm: {frd.n_freqs} excited lines, {frd.freqs[0]:g}-{frd.freqs[-1]:g} Hz, resolution {spacing:g} Hz")
    else:
        from ..frf.periodic import periodic_frf

        exps = read_experiments(data, ins, outs, ts)
        frd = periodic_frf(exps, periods, 1 if transient_periods is None else transient_periods)
        say(f"periodic: {frd.n_freqs} excited lines, {frd.freqs[0]:g}-{frd.freqs[-1]:g} Hz")
    write_table_output(output, frd.to_columns())
    say(f"frequency response written to {output}")


def _read_records(paths, inputs, outputs, ts) -> list:
    """Welch's records: NPZ archives of 1-D float columns are read channel by channel (no table
    copy; samples checked segment batch by segment batch), everything else as experiments."""
    from ..data.sampling import UNIFORM_RTOL
    from ..frf.records import read_npz_record
    from ._common import current_trim

    whole = current_trim() == (None, None)  # a --start/--stop window goes through the table reader
    records = []
    for p in paths:
        rec = (
            read_npz_record(p, inputs, outputs, ts, UNIFORM_RTOL) if whole and str(p).lower().endswith(".npz") else None
        )
        records.append(rec if rec is not None else read_experiments([p], inputs, outputs, ts)[0])
    from ..frf.records import as_channel_records

    return list(as_channel_records([r if hasattr(r, "channels") else as_channel_records(r)[0] for r in records]))


def _check_method_options(method, segment, overlap, window, periods, transient_periods) -> None:
    """Refuse options of another method, and a periodic run without --periods."""
    welch_only = {"--segment": segment, "--overlap": overlap, "--window": window}
    periodic_only = {"--periods": periods, "--transient-periods": transient_periods}
    for name, value in {**welch_only, **periodic_only}.items():
        if value is None:
            continue
        periodic_like = ("periodic", "bla")
        if (name in welch_only and method != "welch") or (name in periodic_only and method not in periodic_like):
            owner = "welch" if name in welch_only else "periodic or bla"
            raise click.UsageError(f"{name} applies to --method {owner}; got --method {method}.")
    if method == "periodic" and periods is None:
        raise click.UsageError("--method periodic needs --periods P (whole periods in each record).")
    if segment is not None and segment < 2:
        raise click.BadParameter(f"must be an integer >= 2; got {segment}.", param_hint="--segment")
    if overlap is not None and not 0.0 <= overlap < 1.0:
        raise click.BadParameter(f"must be a fraction in [0, 1); got {overlap}.", param_hint="--overlap")
