"""``stageid simulate`` and ``stageid freqresp``: run a model file on data or over frequency."""

from __future__ import annotations

from pathlib import Path

import click

from .._errors import DataError, ModelError
from ._common import trim_options
from .outputs import output_option


@click.command(
    "simulate",
    epilog="""
\b
Examples:
  stageid simulate p558.json chirp.csv -o response.csv
  stageid simulate hyst.json drive.csv -o displacement.csv
  stageid simulate model.json record.npz --ts 0.002 -o out.csv
  stageid simulate p558.json z.csv --zero-missing -o response.csv   # inputs z.csv lacks held at 0
  stageid simulate p558.json z.csv --zero-missing --start 1 --stop 2 -o part.csv   # 1 s to 2 s only
  stageid simulate gain.json 20_hz_no_lp.mat -o v.csv   # a dSPACE struct: time X.Data, columns "Y(1).Data" ...
""",
)
@click.argument("model_path", metavar="MODEL.json", type=click.Path(dir_okay=False))
@click.argument("input_path", metavar="INPUT.(csv|npz|mat)", type=click.Path(dir_okay=False))
@output_option("Output .csv or .npz (by extension): `t` then one column per model output.")
@click.option(
    "--ts",
    type=float,
    default=None,
    help="Sample time [s] when the input file has no `t` column (default: the model's dt).",
)
@click.option(
    "--zero-missing",
    is_flag=True,
    help="Drive the model inputs INPUT has no column for with zeros (named on stderr); "
    "without it a missing input is an error.",
)
@trim_options
def simulate_command(model_path: str, input_path: str, output: str, ts: float | None, zero_missing: bool) -> None:
    """Simulate MODEL.json (LTI or hysteresis) driven by the columns of INPUT named like the model's inputs.

    Discrete models run the exact recursion x(k+1) = A x + B u, y = C x + D u from rest;
    continuous models are simulated exactly under a zero-order hold at the input's sample time.
    """
    from ..data.sampling import PERIOD_RTOL, same_period, seconds
    from ..models import load_model
    from ._common import read_table_checked
    from .outputs import check_output, write_table_output

    check_output(output, "table")  # a bad -o is refused before the model is loaded or run
    model = load_model(model_path)
    model_dt = getattr(model, "dt", None)
    rate_independent = not hasattr(model, "frequency_response")  # hysteresis models need no sample time
    file_ts = ts if ts is not None else _default_ts(input_path, model_dt, rate_independent)
    table = read_table_checked(input_path, ts=file_ts)
    u = _model_inputs(table, model.inputs, input_path, zero_missing)
    if model_dt is not None and not same_period(table.dt, model_dt):
        raise DataError(
            f"the input's sample time {seconds(table.dt)} s differs from the model's {seconds(model_dt)} s "
            f"(tolerance {PERIOD_RTOL:g} relative)."
        )
    y = model.simulate(u, dt=table.dt)
    columns = {name: y[:, k] for k, name in enumerate(model.outputs)}
    if rate_independent and ts is None and file_ts is not None:
        write_table_output(output, columns)  # the input had no time axis: none is invented for the output
    else:
        write_table_output(output, columns, dt=table.dt, t0=table.t0)


def _model_inputs(table, inputs, path: str, zero_missing: bool):
    """The model's input columns of ``table``; those it lacks are an error, or zeros with ``zero_missing``."""
    import numpy as np

    from ..checks import shown
    from ._common import say

    missing = [name for name in inputs if name not in table.names]
    if missing and not zero_missing:
        columns = ", ".join(n if len(n) <= 40 else shown(n, 40) for n in table.names[:20])
        more = f" and {len(table.names) - 20} more" if len(table.names) > 20 else ""
        raise DataError(
            f"'{Path(path).name}' has no column for the model's input(s) {', '.join(missing)} "
            f"(its columns: {columns}{more}); add them, or pass --zero-missing to hold them at 0."
        )
    if missing:
        say(f"stageid: note: inputs {', '.join(missing)} are not in '{Path(path).name}': held at 0.", err=True)
    n = table.values.shape[0]
    return np.column_stack([np.zeros(n) if name in missing else table.column(name) for name in inputs])


def _default_ts(path: str, model_dt: float | None, rate_independent: bool) -> float | None:
    """A sample time for a file without a `t` column: the model's dt, or 1 for a rate-independent model.

    None when the file has its own time axis (read_table rejects a ts that disagrees with `t`).
    """
    from ..data.io import read_table

    fallback = model_dt if model_dt is not None else (1.0 if rate_independent else None)
    if fallback is None:
        return None
    try:
        read_table(path, ts=None)
    except DataError as exc:
        if "time column" in str(exc) or "sample time" in str(exc):
            return fallback
        raise
    return None


@click.command(
    "freqresp",
    epilog="""
\b
Examples:
  stageid freqresp p558.json --fmin 1 --fmax 200 --n 400 -o fr.csv
  stageid freqresp maglev.json --fmin 10 --fmax 1000 -o maglev_fr.csv
""",
)
@click.argument("model_path", metavar="MODEL.json", type=click.Path(dir_okay=False))
@click.option("--fmin", type=float, required=True, help="Lowest frequency [Hz], > 0.")
@click.option("--fmax", type=float, required=True, help="Highest frequency [Hz].")
@click.option("--n", "n_points", type=int, default=200, show_default=True, help="Number of log-spaced frequencies.")
@output_option("Output .csv or .npz (by extension).")
def freqresp_command(model_path: str, fmin: float, fmax: float, n_points: int, output: str) -> None:
    """Frequency response of an LTI model at N log-spaced frequencies.

    Columns: `f_hz`, then `re_<output>_<input>` and `im_<output>_<input>` for every
    (output, input) pair, outputs outer, inputs inner.
    """
    import numpy as np

    from ..models import load_model
    from .outputs import check_output, write_table_output

    check_output(output, "table")
    if not (np.isfinite(fmin) and fmin > 0):
        raise click.BadParameter(f"must be a positive number of Hz; got {fmin}.", param_hint="--fmin")
    if not (np.isfinite(fmax) and fmax > fmin):
        raise click.BadParameter(f"must exceed --fmin ({fmin:g}); got {fmax}.", param_hint="--fmax")
    if n_points < 1:
        raise click.BadParameter(f"must be a positive integer; got {n_points}.", param_hint="--n")
    model = load_model(model_path)
    if not hasattr(model, "frequency_response"):
        raise ModelError(f"'{model_path}' is not an LTI model; freqresp needs a stageid.lti/1 file.")
    if model.dt is not None and fmax > 0.5 / model.dt * (1 + 1e-12):
        raise click.BadParameter(
            f"{fmax:g} Hz exceeds the Nyquist frequency {0.5 / model.dt:g} Hz of this discrete model.",
            param_hint="--fmax",
        )
    _require_frequency_work(model, n_points)
    f = np.geomspace(fmin, fmax, n_points) if n_points > 1 else np.array([fmin])
    fr = model.frequency_response(f)
    columns: dict[str, np.ndarray] = {"f_hz": f}
    for i, out_name in enumerate(model.outputs):
        for j, in_name in enumerate(model.inputs):
            columns[f"re_{out_name}_{in_name}"] = fr[:, i, j].real
            columns[f"im_{out_name}_{in_name}"] = fr[:, i, j].imag
    write_table_output(output, columns)


#: Work limit of one frequency response: a solve per frequency, about n_states**3 operations
#: plus a fixed Python overhead per frequency; beyond it the command would run for many minutes.
FREQRESP_WORK_LIMIT = 2e10


def _require_frequency_work(model, n_points: int) -> None:
    """Refuse an ``--n`` whose response would not fit in memory or would run for many minutes."""
    from ..runtime.resources import require_memory, require_work

    n_states = int(getattr(model, "n_states", 0) or 0)  # transfer matrices: polynomial evaluation, cheap
    pairs = model.n_outputs * model.n_inputs
    what = f"--n {n_points} frequencies of a {model.n_outputs}x{model.n_inputs} model"
    # the complex response, its real and imaginary columns, and the table written from them
    require_memory(n_points * (pairs * 64.0 + 32.0), what)
    require_work(n_points * (n_states**3 + 2000.0), FREQRESP_WORK_LIMIT, what, "ask for fewer frequencies")
