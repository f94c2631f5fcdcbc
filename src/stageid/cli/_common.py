"""Helpers shared by the ``stageid`` commands: name lists, reading experiments, deferred messages.

Rules every command follows: bad input raises a :class:`~stageid.StageIdError` (or
``click.UsageError``); ``main`` turns it into one line on stderr and exit code 2.  ``main``
runs every command in one :func:`stageid.atomic.transaction`: the outputs are written to
temporaries and moved into place together when the command has succeeded, and what the
command prints (:func:`say`) is printed after that, so a failed command leaves no file and
prints only its error.  Output files follow the rules of :mod:`.outputs`; progress on
stderr is :mod:`.progress`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import click

__all__ = [
    "split_names",
    "parse_band",
    "read_experiments",
    "read_table_checked",
    "trim_options",
    "channel_options",
    "MODEL_CHANNELS_HELP",
    "TS_HELP",
    "current_trim",
    "say",
    "flush_messages",
    "plain_help",
    "parse_limits",
    "command_line",
    "command_settings",
]


def plain_help(text: str) -> str:
    """Docstring text as help for a terminal: reST roles and double backquotes dropped.

    Examples
    --------
    >>> from stageid.cli._common import plain_help
    >>> plain_help("Swept sine ``a + b``; see :func:`~stageid.signals.chirp`.")
    'Swept sine a + b; see chirp.'
    """
    import re

    text = re.sub(r":[a-z]+:`~?([^`]+)`", lambda m: m.group(1).rsplit(".", 1)[-1], text)
    return text.replace("``", "")


def split_names(text: str | None, option: str) -> tuple[str, ...] | None:
    """``"A,B, C"`` -> ``("A", "B", "C")``; ``None`` stays None. Empty or repeated items are an error."""
    if text is None:
        return None
    from ..checks import shown  # numpy: imported on use, so `stageid --help` starts fast

    names = tuple(s.strip() for s in text.split(","))
    if not names or any(not s for s in names):
        raise click.UsageError(f"{option} must be a comma-separated list of column names; got {shown(text)}.")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise click.UsageError(f"{option} names {shown(repeated[0])} more than once; expected distinct names.")
    return names


def parse_band(text: str, option: str = "--band") -> tuple[float, float]:
    """``"FMIN:FMAX"`` in Hz -> ``(fmin, fmax)`` by the package's one band rule (:func:`stageid.checks.check_band`)."""
    from ..checks import check_band, shown

    try:
        lo, hi = (float(x) for x in text.split(":"))
    except ValueError:
        raise click.UsageError(f"{option} must be FMIN:FMAX in Hz, e.g. 20:300; got {shown(text)}.") from None
    return check_band((lo, hi), option, error=click.UsageError)


def parse_limits(text: str | None, option: str = "--limits") -> tuple[float, float] | None:
    """``"LOW,HIGH"`` -> ``(low, high)``: two finite numbers with ``low < high`` (None stays None)."""
    if text is None:
        return None
    import math

    from ..checks import shown

    try:
        lim = tuple(float(p) for p in text.split(","))
    except ValueError:
        raise click.UsageError(f"{option} must be two numbers LOW,HIGH; got {shown(text)}.") from None
    if len(lim) != 2 or not all(math.isfinite(v) for v in lim) or not lim[0] < lim[1]:
        raise click.UsageError(f"{option} must be two finite numbers LOW,HIGH with LOW < HIGH; got {shown(text)}.")
    return lim[0], lim[1]


_MESSAGES: list[tuple[str, bool]] = []


def say(text: str, err: bool = False) -> None:
    """Print ``text`` (stdout, or stderr with ``err``) once the command has succeeded.

    Results and warnings wait for the outputs to be committed, so a command that fails
    later prints its one error line and nothing else.  A parameter the library names
    (`` `start=0.5` ``) is printed as the flag the user types (``--start 0.5``).
    """
    from .flags import as_flags

    _MESSAGES.append((as_flags(text), err))


def flush_messages(print_them: bool = True) -> None:
    """Print (or drop, after a failure) the messages :func:`say` collected."""
    messages = list(_MESSAGES)
    _MESSAGES.clear()
    if print_them:
        for text, err in messages:
            click.echo(text, err=err)


_TRIM_KEY = "stageid.trim"
_TRIM_HELP = {
    "start": "Drop every record's samples before this time [s] on its time axis (a start-up transient).",
    "stop": "Drop every record's samples after this time [s] on its time axis (an end glitch).",
}


def _remember_trim(ctx: click.Context, param: click.Parameter, value: float | None) -> None:
    import math

    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"expected a finite time in seconds; got {value!r}.")
    ctx.meta.setdefault(_TRIM_KEY, {})[param.name] = value


def trim_options(command):
    """``--start``/``--stop SECONDS``: every record the command reads keeps only that window.

    One decorator for every command that reads time records; the window is applied by
    :func:`read_table_checked` (:meth:`stageid.data.Table.between`), so a command needs no
    parameter of its own for it.
    """
    for name in ("stop", "start"):
        command = click.option(
            f"--{name}",
            name,
            type=float,
            default=None,
            metavar="SECONDS",
            expose_value=False,
            callback=_remember_trim,
            help=_TRIM_HELP[name],
        )(command)
    return command


#: ``--ts`` where a record's sample time comes only from its file or the flag
TS_HELP = "Sample time [s] when the files have no `t` column."
#: ``--inputs`` / ``--outputs`` of the commands that read records against a saved model
MODEL_CHANNELS_HELP = (
    "Input columns (default: the model's input names).",
    "Output columns (default: the model's output names).",
)


def channel_options(inputs_help: str, outputs_help: str, ts_help: str = TS_HELP, required: bool = False):
    """``--inputs``/``--outputs`` (column names, comma-separated) and ``--ts``: which columns of the
    records a command reads, and their sample time when the files carry none."""

    # no explicit ``default`` beside ``required``: click (8.3 on) then takes None as given and skips the check
    names = {"required": True} if required else {"default": None}

    def decorate(command):
        command = click.option("--ts", type=float, default=None, help=ts_help)(command)
        command = click.option("--outputs", help=outputs_help, **names)(command)
        return click.option("--inputs", help=inputs_help, **names)(command)

    return decorate


def current_trim() -> tuple[float | None, float | None]:
    """The ``(start, stop)`` window of the running command (``(None, None)``: whole records)."""
    ctx = click.get_current_context(silent=True)
    window = {} if ctx is None else ctx.find_root().meta.get(_TRIM_KEY, {})
    return window.get("start"), window.get("stop")


def read_table_checked(path: str | os.PathLike[str], ts: float | None):
    """Read a CSV/NPZ/MAT file into a :class:`~stageid.data.io.Table` (``ts`` when no ``t`` column).

    The time axis follows the sample-time rule (:mod:`stageid.data.sampling`); clock jitter
    beyond the stamps' rounding is accepted up to its tolerance and noted in one line.  The
    ``--start``/``--stop`` window of the command (:func:`trim_options`) is applied.
    """
    from ..data.io import read_table
    from ..data.sampling import jitter_note

    table = read_table(path, ts=ts)
    note = jitter_note(table.jitter, table.dt, f"file '{Path(path).name}': ") if table.dt is not None else ""
    if note:
        say(note, err=True)
    start, stop = current_trim()
    return table if start is None and stop is None else table.between(start, stop)


def read_experiments(
    paths: Sequence[str],
    inputs: Sequence[str],
    outputs: Sequence[str],
    ts: float | None,
    fallback_ts: float | None = None,
):
    """One :class:`~stageid.data.Experiment` per file, all checked to share dt and channels.

    ``fallback_ts`` is the sample time of a file with neither a ``t`` column nor ``--ts`` (e.g.
    a discrete model's, when validating it); a time column always wins over it.
    """
    from .._errors import NoSampleTimeError
    from ..data import as_experiments

    exps = []
    for p in paths:
        try:
            table = read_table_checked(p, ts)
        except NoSampleTimeError:
            if fallback_ts is None:
                raise
            table = read_table_checked(p, fallback_ts)
        exps.append(table.experiment(inputs=list(inputs), outputs=list(outputs), name=Path(p).name))
    return as_experiments(exps)


def command_line() -> str | None:
    """The running command as the user typed it (``stageid identify frd a.csv --order 16 ...``),
    for a report to record; None outside a command."""
    import shlex

    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return None
    obj = ctx.find_root().obj
    argv = obj.get("argv") if isinstance(obj, dict) else None
    if argv is None:  # called without main() (a test's CliRunner): the command path at least
        return ctx.command_path
    return shlex.join(["stageid", *argv])


def command_settings() -> dict[str, object]:
    """The running command's options as they were used (``{"--order": 4, ...}``), defaults
    included, for a report to record; empty outside a command."""
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return {}
    out: dict[str, object] = {}
    for param in ctx.command.params:
        if isinstance(param, click.Option) and param.name in ctx.params and not param.hidden:
            out[max(param.opts, key=len)] = ctx.params[param.name]
    return out
