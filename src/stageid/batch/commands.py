"""From a manifest row to a job: which stageid verb it runs, its input files, its output.

A job's command line is checked against the verb's own click definition, the same one the
``stageid`` command parses, so a misspelt option is a manifest error before anything runs.
Path arguments are made absolute against the manifest's folder here, on the client: workers
run the command as given, without changing their working directory (a worker process is shared
by its threads and by Dask's own, so ``chdir`` there would be a race).  Workers must therefore
see the inputs at the same absolute paths (one machine, or a shared file system).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import click

from .._errors import DataError
from .manifest import ManifestRow

__all__ = ["Job", "BATCH_VERBS", "resolve_job"]

#: Verbs a batch can run -> the extension of their output in DIR.  ``plants`` writes a model
#: (.json), or a table (.csv) with ``--experiment``; ``signal`` covers every signal kind.
BATCH_VERBS: dict[str, str] = {
    "identify statespace": ".json",
    "identify closed-loop": ".json",
    "identify hysteresis": ".json",
    "identify frd": ".json",
    "frf": ".csv",
    "simulate": ".csv",
    "freqresp": ".csv",
    "compensate": ".csv",
    "signal": ".csv",
    "plants": ".json",
}
_HELP = ("-h", "--help")


@dataclass(frozen=True)
class Job:
    """A checked job: ``argv`` is the command line to run (paths absolute) without ``-o``.

    ``inputs`` pairs each input path as the manifest gives it with its absolute path;
    ``suffix`` is the output's extension (``.json`` or ``.csv``).
    """

    name: str
    command: str
    verb: str
    argv: tuple[str, ...]
    inputs: tuple[tuple[str, str], ...]
    suffix: str

    @property
    def output_name(self) -> str:
        return self.name + self.suffix


def resolve_job(row: ManifestRow, root: click.Group, base: str) -> Job:
    """Check ``row``'s command against the stageid command tree ``root``; paths made absolute.

    Raises
    ------
    DataError
        Not a verb a batch can run (``batch`` itself, ``report``, ``export``...), an ``-o`` or
        ``--report`` in the command (the batch names the output), ``--help``, or a command
        line the verb's own parser refuses (unknown option, missing argument, bad value).
    """
    where = f"manifest row {row.row} ({row.name})"
    ctx = click.Context(root, info_name="stageid")
    words = list(row.words)
    command: click.Command = root
    path: list[str] = []
    while isinstance(command, click.Group):
        sub = command.get_command(ctx, words[0]) if words and not words[0].startswith("-") else None
        if sub is None:
            given = " ".join([*path, *words[:1]]) or row.command
            raise DataError(f"{where}: {given!r} is not a stageid verb a batch can run; expected one of {_verbs()}.")
        path.append(words.pop(0))
        command = sub
    verb = " ".join(path[:1] if path[0] == "signal" else path)
    if verb not in BATCH_VERBS:
        raise DataError(f"{where}: 'stageid {' '.join(path)}' cannot run in a batch; expected one of {_verbs()}.")
    output_param = _output_param(command)
    _refuse_outputs(command, output_param, words, where)
    located = _path_positions(command, words)
    argv = list(words)
    for i, prefix in located:
        value = argv[i][len(prefix) :]
        argv[i] = prefix + (value if os.path.isabs(value) or value == "" else os.path.join(base, value))
    params = _parse(command, " ".join(path), argv, where)
    inputs = [(words[i][len(p) :], argv[i][len(p) :]) for i, p in located]
    # the parser is the authority on which words are paths: every path it read must be one we made absolute
    parsed = {str(v) for p in command.params if _is_input(p, output_param) for v in _values(params.get(p.name))}
    if parsed != {absolute for _, absolute in inputs}:
        raise DataError(f"{where}: cannot tell the input files apart from other words; expected plain PATH arguments.")
    suffix = ".csv" if verb == "plants" and params.get("experiment") is not None else BATCH_VERBS[verb]
    return Job(row.name, row.command, " ".join(path), (*path, *argv), tuple(inputs), suffix)


def _verbs() -> str:
    return ", ".join(v + (" KIND" if v == "signal" else "") for v in BATCH_VERBS)


def _output_param(command: click.Command) -> click.Parameter | None:
    return next((p for p in command.params if isinstance(p, click.Option) and "-o" in p.opts), None)


def _is_input(param: click.Parameter, output_param: click.Parameter | None) -> bool:
    """A file the command reads: a Path parameter that is neither ``-o`` nor a report folder."""
    return param is not output_param and isinstance(param.type, click.Path) and param.type.file_okay


def _values(value: object) -> tuple:
    if value is None:
        return ()
    return tuple(value) if isinstance(value, (tuple, list)) else (value,)


def _option_names(param: click.Parameter) -> list[str]:
    return [*param.opts, *getattr(param, "secondary_opts", [])]


def _refuse_outputs(command: click.Command, output_param, words: list[str], where: str) -> None:
    """``-o`` (the batch names the output), output folders (``--report``) and ``--help``."""
    refused = {name: "-o" for name in (_option_names(output_param) if output_param else [])}
    for p in command.params:
        if isinstance(p, click.Option) and isinstance(p.type, click.Path) and not p.type.file_okay:
            refused.update({name: name for name in _option_names(p)})
    refused.update({h: h for h in _HELP})
    for word in words:
        if word == "--":
            break
        name = word.split("=", 1)[0]
        hit = refused.get(name) or ("-o" if word.startswith("-o") and not word.startswith("--") else None)
        if hit == "-o":
            raise DataError(f"{where}: the command has {word!r}; expected no -o (the batch writes DIR/<name>).")
        if hit:
            raise DataError(f"{where}: the command has {name}; a batch job writes only its DIR/<name> output.")


def _path_positions(command: click.Command, words: list[str]) -> list[tuple[int, str]]:
    """(index, prefix) of the words holding input paths: ``--controller K.json``, ``--x=K.json``
    (prefix ``--x=``) and PATH arguments, assigned to arguments by click's nargs rule."""
    output_param = _output_param(command)
    options = {n: p for p in command.params if isinstance(p, click.Option) for n in _option_names(p)}
    found: list[tuple[int, str]] = []
    positional: list[int] = []
    i, only_positional = 0, False
    while i < len(words):
        word = words[i]
        if only_positional or word == "-" or not word.startswith("-"):
            positional.append(i)
        elif word == "--":
            only_positional = True
        else:
            name, eq, _ = word.partition("=")
            param = options.get(name)
            if param is not None and not (param.is_flag or param.count):
                if _is_input(param, output_param):
                    found += [(i, name + "=")] if eq else [(j, "") for j in range(i + 1, i + 1 + param.nargs)]
                i += 0 if eq else param.nargs
        i += 1
    arguments = [p for p in command.params if isinstance(p, click.Argument)]
    fixed = sum(max(p.nargs, 0) for p in arguments)
    start = 0
    for p in arguments:
        count = p.nargs if p.nargs >= 0 else max(len(positional) - fixed, 0)
        if _is_input(p, output_param):
            found += [(j, "") for j in positional[start : start + count]]
        start += count
    return sorted(j for j in found if j[0] < len(words))


def _parse(command: click.Command, verb: str, argv: list[str], where: str) -> dict:
    """The verb's own parser on the job's command line (with a stand-in ``-o``): its values."""
    stand_in = ["-o", "batch-output"] if _output_param(command) else []  # parsed, never written
    try:
        with click.Context(click.Group("stageid"), info_name="stageid") as parent:
            ctx = command.make_context(verb, [*argv, *stand_in], parent=parent)
    except click.exceptions.Exit:
        raise DataError(f"{where}: the command only prints; expected one that writes an output.") from None
    except click.ClickException as exc:
        raise DataError(f"{where}: {' '.join(exc.format_message().split())}") from None
    return ctx.params
