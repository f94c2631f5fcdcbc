"""The output files of the ``stageid`` commands: checked before any work, written atomically.

One rule for every verb: check ``-o`` with :func:`check_output` *before any work* (its
extension picks the format, its directory must exist and is never created, ``-`` is refused,
an input of the command is refused), then write with :func:`write_table_output` (tables:
``.csv`` or ``.npz``) or :func:`write_model_output` (models: ``.json``).  Report folders:
:func:`check_output_folder` (the same rules; the folder itself may be created).
"""

from __future__ import annotations

import os
from pathlib import Path

import click

from .._errors import DataError
from ..atomic import check_not_input, check_parent, note_input

__all__ = [
    "output_option",
    "check_output",
    "check_output_folder",
    "write_table_output",
    "write_model_output",
    "TABLE_SUFFIXES",
    "MODEL_SUFFIXES",
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


def output_option(help_text: str, name: str = "output"):
    """The required ``-o/--output FILE`` option of a command, passed as ``name`` (checked by :func:`check_output`)."""
    return click.option("-o", "--output", name, required=True, type=click.Path(dir_okay=False), help=help_text)


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
    >>> from stageid.cli.outputs import check_output
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
