"""``stageid signal KIND [options] -o FILE``: write an excitation signal to CSV or NPZ.

One sub-command per kind of :data:`stageid.signals.SIGNAL_KINDS`; its options are built
from the generator's signature, so ``stageid signal chirp --help`` lists exactly what
:func:`stageid.signals.chirp` accepts.
"""

from __future__ import annotations

import inspect
from typing import Any

import click

from .._errors import DataError, SignalError
from ._common import plain_help

_EXAMPLES = {
    "chirp": "stageid signal chirp --f0 1 --f1 100 --duration 10 --dt 0.002 --amplitude 20 --offset 20 --name Z -o z_chirp.csv",
    "prbs": "stageid signal prbs --n-samples 5000 --dt 0.002 --n-channels 3 --names Z,Rx,Ry -o prbs.csv",
    "multisine": "stageid signal multisine --n-samples 8192 --dt 1e-4 --f-low 10 --f-high 2000 --n-periods 4 --lines random-odd --crest-iterations 100 --realisations 8 --seed 1 --name V -o ms.csv",
    "decaying-triangle": "stageid signal decaying-triangle --freq 1 --n-cycles 10 --dt 0.001 --amplitude 500 --name V -o drive.csv",
}


def _limits(value: str | None) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        lo, hi = (float(s) for s in value.split(":"))
    except ValueError:
        raise click.BadParameter(f"must be LO:HI, e.g. -500:500; got {value!r}.", param_hint="--limits") from None
    return lo, hi


def _click_type(param: inspect.Parameter) -> Any:
    ann = (
        param.annotation
        if isinstance(param.annotation, str)
        else getattr(param.annotation, "__name__", str(param.annotation))
    )
    ann = ann.replace("typing.", "").strip()
    if ann.startswith("int"):
        return int
    if ann.startswith("float"):
        return float
    return str


def _param_help(func: Any) -> dict[str, str]:
    """First description line of each parameter in a numpydoc ``Parameters`` section."""
    doc = inspect.getdoc(func) or ""
    lines = doc.splitlines()
    helps: dict[str, str] = {}
    try:
        start = lines.index("Parameters") + 2
    except ValueError:
        return helps
    current: list[str] = []
    for i in range(start, len(lines)):
        line = lines[i]
        if i + 1 < len(lines) and lines[i + 1].strip() and set(lines[i + 1].strip()) == {"-"}:
            break  # the next numpydoc section begins
        if line and not line.startswith(" "):
            current = [n.strip() for n in line.split(" : ")[0].split(",")]
        elif line.strip() and current:
            for name in current:
                helps.setdefault(name, plain_help(line.strip()))
            current = []
    return helps


def _generator_option(name: str, p: inspect.Parameter, help_text: str | None) -> click.Option:
    """The option of one generator parameter: required when it has no default."""
    flag = "--" + name.replace("_", "-")
    if name == "limits":
        return click.Option(
            [flag], type=str, default=None, help="Allowed range LO:HI; exceeding it is an error (never clipped)."
        )
    required = p.default is inspect.Parameter.empty
    default = None if required else p.default
    return click.Option(
        [flag, name],
        type=click.IntRange(min=0) if name == "seed" else _click_type(p),
        required=required,
        default=default,
        show_default=not required and default is not None,
        help=help_text,
    )


def _options(kind: str) -> list[click.Parameter]:
    """The generator's parameters as options, then ``--dt`` (if the generator has none), names and ``-o``."""
    from ..signals import SIGNAL_KINDS, signal_parameters

    params = {n: p for n, p in signal_parameters(kind).items() if (kind, n) not in _PER_FILE}
    helps = _param_help(SIGNAL_KINDS[kind])
    options: list[click.Parameter] = [_generator_option(name, p, helps.get(name)) for name, p in params.items()]
    if kind == "multisine":
        options.append(
            click.Option(
                ["--realisations", "realisations"],
                type=click.IntRange(min=1),
                default=1,
                show_default=True,
                help="Random-phase realisations, one file each (FILE_r01, ...); lines and amplitudes shared.",
            )
        )
    if "dt" not in params:
        options.append(
            click.Option(
                ["--dt", "dt"],
                type=float,
                default=None,
                help="Sample time [s] for the `t` column (omitted when not given).",
            )
        )
    options.append(
        click.Option(
            ["--name", "--names", "names"],
            type=str,
            default="u",
            show_default=True,
            help="Column name(s), comma-separated for several channels.",
        )
    )
    options.append(
        click.Option(
            ["-o", "--output", "output"], required=True, type=click.Path(dir_okay=False), help="Output .csv or .npz."
        )
    )
    return options


#: Generator parameters the command sets per written file instead of taking as options.
_PER_FILE = {("multisine", "realisation"), ("multisine", "experiment")}


def _write_signal(kind: str, kwargs: dict[str, Any]) -> None:
    """Generate the signal from the parsed options and write it with one column per channel."""
    import numpy as np

    from ..data.columns import TIME_COLUMN
    from ..signals import generate, signal_parameters
    from ._common import split_names
    from .outputs import check_output, write_table_output

    params = signal_parameters(kind)
    output = check_output(kwargs.pop("output"), "table")
    names = list(split_names(kwargs.pop("names"), "--names") or ())
    if TIME_COLUMN in names:
        raise DataError(f"--name '{TIME_COLUMN}' is reserved for the time column; expected another column name.")
    dt_for_file = kwargs.get("dt") if "dt" in params else kwargs.pop("dt")
    if "limits" in kwargs:
        kwargs["limits"] = _limits(kwargs["limits"])
    realisations = kwargs.pop("realisations", 1)
    kwargs = {k: v for k, v in kwargs.items() if not (v is None and params[k].default is None)}
    if kind == "multisine":
        from .multisine_files import write_multisine_files

        write_multisine_files(output, kwargs, realisations, lambda x: signal_columns(x, names), dt_for_file)
        return
    x = np.asarray(generate(kind, **kwargs))
    write_table_output(output, signal_columns(x, names), dt=dt_for_file)


def signal_columns(x: Any, names: list[str]) -> dict[str, Any]:
    """One column per channel of ``x``; a single name gets numbered for several channels."""
    x2 = x[:, None] if x.ndim == 1 else x
    if len(names) == 1 and x2.shape[1] > 1:
        names = [f"{names[0]}{i + 1}" for i in range(x2.shape[1])]
    if len(names) != x2.shape[1]:
        raise SignalError(f"--names must give {x2.shape[1]} column names; got {len(names)}.")
    return {n: x2[:, i] for i, n in enumerate(names)}


def _make_command(kind: str) -> click.Command:
    from ..signals import SIGNAL_KINDS

    def callback(**kwargs: Any) -> None:
        _write_signal(kind, kwargs)

    summary = plain_help((inspect.getdoc(SIGNAL_KINDS[kind]) or kind).splitlines()[0])
    epilog = f"\b\nExample:\n  {_EXAMPLES[kind]}" if kind in _EXAMPLES else None
    return click.Command(
        kind, params=_options(kind), callback=callback, help=summary, short_help=summary, epilog=epilog
    )


class _SignalGroup(click.Group):
    """Builds the per-kind sub-commands on first use, so other commands start fast."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        from ..signals import SIGNAL_KINDS

        return list(SIGNAL_KINDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        from ..signals import SIGNAL_KINDS

        return _make_command(name) if name in SIGNAL_KINDS else None


@click.group("signal", cls=_SignalGroup, epilog="\b\nExamples:\n  " + "\n  ".join(_EXAMPLES.values()))
def signal_command() -> None:
    """Write an excitation signal (one column per channel, plus `t` when dt is known)."""
