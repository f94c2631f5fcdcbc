"""Helpers shared by the ``stageid`` commands: name lists, reading experiments, safe outputs.

Rules every command follows: bad input raises a :class:`~stageid.StageIdError` (or
``click.UsageError``); ``main`` turns it into one line on stderr and exit code 2.  ``main``
runs every command in one :func:`stageid.atomic.transaction`: the outputs are written to
temporaries and moved into place together when the command has succeeded, and what the
command prints (:func:`say`) is printed after that, so a failed command leaves no file and
prints only its error.

Output files, one rule for every verb: check ``-o`` with :func:`check_output` *before any
work* (its extension picks the format, its directory must exist and is never created, ``-``
is refused, an input of the command is refused), then write with :func:`write_table_output`
(tables: ``.csv`` or ``.npz``) or :func:`write_model_output` (models: ``.json``).  Report
folders: :func:`check_output_folder` (the same rules; the folder itself may be created).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import click

from .._errors import DataError
from ..atomic import check_not_input, check_parent, note_input

__all__ = [
    "split_names",
    "parse_band",
    "read_experiments",
    "read_table_checked",
    "trim_options",
    "current_trim",
    "say",
    "flush_messages",
    "check_output",
    "check_output_folder",
    "write_table_output",
    "write_model_output",
    "TABLE_SUFFIXES",
    "MODEL_SUFFIXES",
    "progress",
    "StepProgress",
    "is_interactive",
    "plain_help",
]

#: Extensions of table outputs (signals, simulated records, frequency responses), by format.
TABLE_SUFFIXES = (".csv", ".npz")
#: Extensions of model outputs (stageid.lti/1 and the hysteresis formats are JSON).
MODEL_SUFFIXES = (".json",)
#: kind of an ``-o`` file -> (its extensions, the words in messages)
_OUTPUT_KINDS = {
    "table": (TABLE_SUFFIXES, "a table"),
    "model": (MODEL_SUFFIXES, "a model"),
    "mat": ((".mat",), "a MATLAB file"),
}


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
    later prints its one error line and nothing else.
    """
    _MESSAGES.append((text, err))


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


def _command_inputs() -> list[str]:
    """The files the running command reads: its path arguments and its ``*_path`` options."""
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return []
    paths: list[str] = []
    for param in ctx.command.params:
        if not isinstance(param.type, click.Path) or not (
            isinstance(param, click.Argument) or (param.name or "").endswith("_path")
        ):
            continue
        value = ctx.params.get(param.name or "")
        paths += [str(v) for v in (value if isinstance(value, tuple) else (value,)) if v]
    return paths


def _protect_inputs(target: Path) -> None:
    """Register the command's input files with the output transaction; refuse ``target`` if it is one."""
    for source in _command_inputs():
        note_input(source)
    check_not_input(target)


def check_output(path: str | os.PathLike[str], kind: str) -> Path:
    """Check an ``-o`` path before any work is done; returns it as a Path.

    Parameters
    ----------
    path : str or path-like
        The output file.
    kind : {"table", "model", "mat"}
        A table is written as CSV or NPZ by its extension (:data:`TABLE_SUFFIXES`); a model
        as JSON (:data:`MODEL_SUFFIXES`); a MATLAB export as ``.mat``.

    Raises
    ------
    DataError
        ``-`` (standard output is not supported), an extension that does not match the
        kind, a missing directory, or a path that is an existing directory.

    Examples
    --------
    >>> from stageid.cli._common import check_output
    >>> check_output("fr.npz", "table").suffix
    '.npz'
    >>> check_output("fr.mat", "table")
    Traceback (most recent call last):
    ...
    stageid._errors.DataError: output 'fr.mat' has extension '.mat'; expected .csv or .npz for a table.
    """
    if kind not in _OUTPUT_KINDS:
        raise ValueError(f"kind must be one of {', '.join(_OUTPUT_KINDS)}; got {kind!r}.")
    allowed, words = _OUTPUT_KINDS[kind]
    if str(path) == "-":
        raise DataError(
            f"-o '-' (standard output) is not supported; expected a file name ending in {' or '.join(allowed)}."
        )
    target = Path(path)
    suffix = target.suffix.lower()
    if suffix not in allowed:
        shown = f"extension '{suffix}'" if suffix else "no extension"
        # a bare name is most often a column given to -o/--output (a file) instead of --outputs
        hint = "" if suffix else " -o names the file to write, not a data column."
        raise DataError(f"output '{target}' has {shown}; expected {' or '.join(allowed)} for {words}.{hint}")
    check_parent(target)
    if target.is_dir():
        raise DataError(f"cannot write '{target}': it is a directory; expected a file name.")
    _protect_inputs(target)
    return target


def check_output_folder(path: str | os.PathLike[str], what: str = "a report") -> Path:
    """Check a report folder (``--out``/``--report``) before any work: its parent must exist.

    Raises
    ------
    DataError
        A missing parent directory, ``-``, or an existing file at ``path``.
    """
    if str(path) == "-":
        raise DataError(f"the folder for {what} cannot be '-' (standard output); expected a folder name.")
    target = check_parent(path)
    if target.exists() and not target.is_dir():
        raise DataError(f"cannot write {what} into '{target}': it is a file; expected a folder.")
    _protect_inputs(target)
    return target


def write_table_output(path: str | os.PathLike[str], data, *, dt: float | None = None, t0: float | None = None) -> Path:
    """Write a table to ``path`` as CSV or NPZ, chosen by its extension, atomically.

    ``data`` and ``dt``/``t0`` as :func:`stageid.data.write_csv`.  Raises :class:`DataError`
    as :func:`check_output` and the writers.
    """
    from ..data.io import write_csv, write_npz

    target = check_output(path, "table")
    writer = write_npz if target.suffix.lower() == ".npz" else write_csv
    return writer(target, data, dt=dt, t0=t0)


def write_model_output(path: str | os.PathLike[str], model) -> Path:
    """Save a model as JSON at ``path`` atomically (checked as :func:`check_output` ``"model"``)."""
    from ..models.serialization import save_model

    target = check_output(path, "model")
    save_model(model, target)
    return target


def is_interactive() -> bool:
    """True when stderr is a terminal (progress bars only make sense there)."""
    import sys

    return sys.stderr.isatty()


def progress(total: int | None = None, desc: str = "", unit: str = "it"):
    """A tqdm progress bar on stderr, silent when stderr is not a terminal."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not is_interactive(), leave=False)


class StepProgress:
    """Progress of a long fit on stderr, as the callback ``(step, done, total)`` of
    :meth:`stageid.hysteresis.stage_identification.StageIdentifier.fit`.

    On a terminal: a tqdm bar per counted step, with the time left that tqdm estimates from the
    rate so far, and the step's name for steps without a count (bars are removed when done).
    Otherwise (a log, a pipe): a line ``[elapsed] step done/total, about N s left`` when a
    counted step starts, after its first candidate, at its end and otherwise at most every
    ``interval`` seconds, so a log shows that the fit moves without one line per candidate;
    steps without a count get a line only once counting has begun (the input checks come
    before it, and a command refused there prints only its one-line error).
    """

    def __init__(self, interval: float = 30.0) -> None:
        import time

        self._clock = time.perf_counter
        self._start = self._clock()
        self._interval = interval
        self._step: str | None = None
        self._step_start = self._start
        self._last_line = -float("inf")
        self._bar = None
        self._counted = False

    def __call__(self, step: str, done: int, total: int) -> None:
        now = self._clock()
        if step != self._step:
            self.close()
            self._step, self._step_start, self._last_line = step, now, -float("inf")
            if is_interactive() and total:
                self._bar = progress(total, step, "candidate")
            elif is_interactive():  # no count: the step's name and its elapsed time
                from tqdm.auto import tqdm

                self._bar = tqdm(desc=step, bar_format="{desc} [{elapsed}]", leave=False)
        if self._bar is not None:
            self._bar.update(done - self._bar.n)
            return
        if not total:
            if self._counted:  # before the count starts a failing command must print only its error
                self._line(now, step)
            return
        self._counted = True
        if done <= 1 or done == total or now - self._last_line >= self._interval:
            text = f"{step} {done}/{total}"
            if 0 < done < total:
                text += f", about {(now - self._step_start) / done * (total - done):.0f} s left"
            self._line(now, text)

    def _line(self, now: float, text: str) -> None:
        click.echo(f"[{now - self._start:5.0f} s] {text}", err=True)
        self._last_line = now

    def close(self) -> None:
        """Remove the terminal's bar (the command prints its result after this)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
