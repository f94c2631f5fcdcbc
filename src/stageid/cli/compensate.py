"""``stageid compensate``: feedforward drive from a hysteresis model and a desired trajectory."""

from __future__ import annotations

import click

from .._errors import DataError
from ._common import say
from .outputs import output_option


@click.command(
    "compensate",
    epilog="""
\b
Examples:
  stageid compensate hyst.json ref.csv --column yref -o drive.csv
  stageid compensate hyst.json ref.csv --column yref --limits -500,500 -o drive.csv
""",
)
@click.argument("model_path", metavar="HYST.json", type=click.Path(dir_okay=False))
@click.argument("ref_path", metavar="REF.(csv|npz|mat)", type=click.Path(dir_okay=False))
@click.option("--column", required=True, help="Column of REF holding the desired output.")
@click.option(
    "--limits",
    default=None,
    help="Drive limits LOW,HIGH (default: the model's input_limits, i.e. the identified input range of "
    "a model from `stageid identify hysteresis`, else none). The drive is clipped to them; a "
    "warning tells when the reference needs drives outside the model's input_limits.",
)
@click.option("--ts", type=float, default=None, help="Sample time [s] when REF has no `t` column.")
@output_option("Drive .csv or .npz (by extension): columns `t` and the model's input name.", "out")
def cli(model_path: str, ref_path: str, column: str, limits: str | None, ts: float | None, out: str) -> None:
    """Inverse-model feedforward: the drive that makes the hysteresis model follow REF's COLUMN.

    A stage model with dynamics (`identify hysteresis --dynamics`) is inverted offline over the
    whole reference: stable inversion of its linear dynamics (preview allowed, regularised by
    the least decade whose drive needs no extra clipping), then the hysteresis inverse (with a
    Preisach stage's creep), clipped to the drive limits.

    Classical PI models use their closed-form inverse; modified PI models are inverted sample
    by sample (exact to 1e-12); Preisach models by their exact inverse (one linear
    interpolation per sample, exact to rounding). The drive starts from the model's stored
    state; a model with a creep term is inverted at the reference file's sampling period.
    """
    from ..hysteresis import Compensator
    from ..hysteresis.models.pi import ModifiedPIModel, PIModel
    from ..hysteresis.models.preisach import PreisachModel
    from ..hysteresis.stage import StageModel
    from ..models import load_model
    from ._common import parse_limits, read_table_checked
    from .outputs import check_output, write_table_output

    check_output(out, "table")  # a bad -o is refused before the model is loaded or inverted
    model = load_model(model_path)
    stage = model if isinstance(model, StageModel) else None
    if stage is not None:
        model = stage.hysteresis
    if not isinstance(model, (PIModel, ModifiedPIModel, PreisachModel)):
        raise DataError(f"'{model_path}' is not a hysteresis model (stageid.hysteresis/1); got {type(model).__name__}.")
    lim = parse_limits(limits)
    table = read_table_checked(ref_path, ts=ts)
    yref = table.column(column)
    if table.dt is None:
        raise DataError(f"'{ref_path}' has no `t` column; give its sample time with --ts.")
    if stage is not None and (stage.dynamics is not None or stage.creep is not None):
        from ..hysteresis.stage.inverse import stage_feedforward

        # offline: stable inversion of the dynamics over the whole reference, then the hysteresis
        # (a Preisach stage's creep folded into its exact inverse)
        u = stage_feedforward(stage, yref, table.dt, limits=lim)
    elif isinstance(model, PreisachModel):
        from ..hysteresis.inverse.preisach import preisach_feedforward

        u = preisach_feedforward(model, yref, limits=lim)
    else:
        # a creep term (rate dependent) runs at the reference's sampling period
        u = Compensator(model, limits=lim, dt=table.dt).run(yref)
    write_table_output(out, {model.inputs[0]: u[:, 0]}, dt=table.dt, t0=table.t0)
    _warn_outside_range(model, lim, u[:, 0])


def _warn_outside_range(model, limits: tuple[float, float] | None, u) -> None:
    """One warning line when the drive leaves (or, clipped, would leave) ``model.input_limits``."""
    import numpy as np

    if model.input_limits is None or u.size == 0:
        return
    lo, hi = model.input_limits
    name = model.inputs[0]
    if limits is None:  # clipped to the model's limits: samples sitting on a limit wanted more
        tol = 1e-9 * (hi - lo)
        n = int(np.count_nonzero((u <= lo + tol) | (u >= hi - tol)))
        if n:
            say(
                f"stageid: warning: the reference needs drives outside the model's input_limits "
                f"[{lo:g}, {hi:g}] {name} (identified range): {n} of {u.size} drive samples clipped there; "
                f"give --limits to extrapolate.",
                err=True,
            )
    else:
        n = int(np.count_nonzero((u < lo) | (u > hi)))
        if n:
            say(
                f"stageid: warning: {n} of {u.size} drive samples lie outside the model's input_limits "
                f"[{lo:g}, {hi:g}] {name} (identified range); the model is extrapolated there.",
                err=True,
            )
