"""``stageid export c`` and ``stageid export mat``: models for real-time targets and MATLAB."""

from __future__ import annotations

from pathlib import Path

import click

from .._errors import DataError
from ._common import parse_limits
from .outputs import check_output, check_output_folder

_METHODS = click.Choice(["zoh", "tustin"])


@click.group(
    "export",
    epilog="""
\b
Examples:
  stageid export c hyst.json --prefix comp --inverse -o build/     # build/comp.h, build/comp.c
  stageid export c stage.json --prefix stage --float -o build/
  stageid export c plant.json --prefix plant --dt 1e-4 --method tustin -o build/
  stageid export mat stage.json -o stage.mat
""",
)
def export_group() -> None:
    """Export a model: self-contained C99 code, or a MATLAB v5 MAT file."""


def _dt_option(f):
    f = click.option(
        "--method", type=_METHODS, default=None, help="Discretisation of a continuous LTI model (default zoh)."
    )(f)
    return click.option(
        "--dt",
        type=float,
        default=None,
        help="Sample time [s]: discretises a continuous LTI model; for a hysteresis model with creep, the "
        "sampling period of its lags (default the creep's sample_time).",
    )(f)


@export_group.command(
    "c",
    epilog="""
\b
Examples:
  stageid export c hyst.json --prefix comp --inverse -o build/
  gcc -std=c99 -O2 -c build/comp.c      # then comp_init(&s) once, comp_step(&s, &y_ref, &u) per sample
""",
)
@click.argument("model_path", metavar="MODEL.json", type=click.Path(dir_okay=False))
@click.option("--prefix", required=True, help="C identifier starting every exported name: P.h, P.c, P_step ...")
@click.option("-o", "--output", "out_dir", required=True, help="Folder for P.h and P.c (created if missing).")
@click.option(
    "--inverse",
    is_flag=True,
    help="The streaming compensator (desired output -> drive) of a hysteresis model; of a stage model, of its "
    "hysteresis (the dynamics are not inverted: their stable inversion is offline, `stageid compensate`).",
)
@click.option("--float", "single", is_flag=True, help="Single-precision arithmetic (default double).")
@click.option(
    "--limits", default=None, help="Drive limits LOW,HIGH of the compensator (default the model's input_limits)."
)
@_dt_option
def c_command(
    model_path: str,
    prefix: str,
    out_dir: str,
    inverse: bool,
    single: bool,
    limits: str | None,
    dt: float | None,
    method: str | None,
) -> None:
    """Write self-contained C99 code of MODEL.json: P.h (P_N_INPUTS, P_N_OUTPUTS, P_state, P_init,
    P_step) and P.c. No heap, no I/O, no mutable globals; reproduces `stageid simulate` (or, with
    --inverse, `stageid compensate` of a hysteresis model) to rounding in double precision. A
    stage model runs its hysteresis, creep and dynamics sample by sample."""
    from ..export import check_prefix, export_c
    from ..models import load_model

    check_prefix(prefix)
    folder = check_output_folder(out_dir, "the .h and .c files")
    drive_limits = parse_limits(limits)
    step = _check_dt(dt)
    model = load_model(model_path)
    code = export_c(
        model,
        prefix,
        inverse=inverse,
        single=single,
        dt=step,
        method=method,
        limits=drive_limits,
        source=Path(model_path).name,
    )
    _write_files(folder, code.files())
    click.echo(f"wrote {folder / (prefix + '.h')} and {folder / (prefix + '.c')}")
    if inverse and getattr(model, "kind", None) == "stage" and model.dynamics is not None:
        from ..export.c_stage import STAGE_INVERSE_NOTE

        click.echo(f"note: {STAGE_INVERSE_NOTE}.")


@export_group.command(
    "mat",
    epilog="""
\b
Examples:
  stageid export mat stage.json -o stage.mat
  % MATLAB: m = load('stage.mat'); sys = ss(m.A, m.B, m.C, m.D, m.Ts, 'InputName', m.InputName, 'OutputName', m.OutputName);
""",
)
@click.argument("model_path", metavar="MODEL.json", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, help="The .mat file (MATLAB v5).")
@_dt_option
def mat_command(model_path: str, out: str, dt: float | None, method: str | None) -> None:
    """Write MODEL.json as a MATLAB v5 MAT file: A, B, C, D, Ts, InputName, OutputName as `ss()`
    takes them, or a struct `hysteresis` of a hysteresis model's parameters; a stage model as
    both (its dynamics' ss() arguments and num/den in z^-1 beside the struct `hysteresis`)."""
    from ..atomic import atomic_write
    from ..export.matlab import export_mat, mat_variables
    from ..models import load_model

    target = check_output(out, "mat")
    step = _check_dt(dt)
    model = load_model(model_path)
    mat_variables(model, step, method)  # every check before anything is written
    atomic_write(target, lambda fh: export_mat(model, fh, step, method), binary=True)
    click.echo(f"wrote {target}")


def _check_dt(dt: float | None) -> float | None:
    from ..checks import check_real

    return None if dt is None else check_real(dt, "--dt", "export", low=0.0, closed="right", error=DataError)


def _write_files(folder: Path, files: dict[str, str]) -> None:
    """Write every file or none (:func:`stageid.atomic.staged_folder`): the files go to a
    temporary folder next to ``folder`` and move into place together at the command's end."""
    from ..atomic import staged_folder

    with staged_folder(folder) as tmp:
        for name, text in files.items():
            (tmp / name).write_text(text)
