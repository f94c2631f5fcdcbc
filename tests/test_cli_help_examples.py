"""Every ``stageid ...`` example in the command line's help texts works as printed.

The main help's examples chain (each reads what the earlier ones wrote) and must all run; then
every command's examples run in the same folder when the files they read exist there.  An
example that reads a file no example writes (a user's own record) must still parse, and fail
on that missing file only, never on an option or a value the command no longer takes.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import click
import pytest

from conftest import run_main
from stageid.cli.main import cli

#: Commands whose examples are only parsed, not run: each takes longer than a unit test should.
PARSE_ONLY = {
    ("demo",): "runs the three workflows with their reports (tens of seconds)",
    ("serve",): "serves until stopped (the app tests start it)",
}


def example_lines(epilog: str) -> list[list[str]]:
    """The ``stageid ...`` lines of a help epilog as argument lists (``#`` comments dropped,
    ``\\`` continuations joined)."""
    lines, pending = [], None
    for raw in epilog.splitlines():
        text = raw.split("#")[0].rstrip()
        if pending is not None:
            text, pending = pending + " " + text.strip(), None
        elif not text.strip().startswith("stageid "):
            continue
        if text.endswith("\\"):
            pending = text[:-1].rstrip()
            continue
        lines.append(shlex.split(text)[1:])
    return lines


def help_examples(command: click.Command = cli, path: tuple[str, ...] = ()):
    """(command path, its example lines) for ``command`` and every sub-command, the group first."""
    yield path, example_lines(command.epilog or "")
    if isinstance(command, click.Group):
        ctx = click.Context(command)
        for name in command.list_commands(ctx):
            yield from help_examples(command.get_command(ctx, name), path + (name,))


def parsed(args: list[str]) -> tuple[tuple[str, ...], click.Context]:
    """The command path an example names and its parsed context (raises click errors on bad options)."""
    command, rest, path = cli, list(args), []
    while isinstance(command, click.Group):
        name = rest.pop(0) if rest else ""
        sub = command.get_command(click.Context(command), name)
        if sub is None:
            raise click.UsageError(f"no command {name!r}")
        command, path = sub, path + [name]
    return tuple(path), command.make_context(" ".join(path), rest)


def input_files(ctx: click.Context) -> list[str]:
    """The files an example reads: its path arguments and its ``*_path`` options."""
    files: list[str] = []
    for param in ctx.command.params:
        if isinstance(param.type, click.Path) and (
            isinstance(param, click.Argument) or (param.name or "").endswith("_path")
        ):
            value = ctx.params.get(param.name or "")
            files += [str(v) for v in (value if isinstance(value, tuple) else (value,)) if v]
    return files


def test_the_examples_of_every_help_text_run_or_fail_only_on_a_missing_record(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ran, missing, failures = [], [], []
    for help_path, lines in help_examples():
        for args in lines:
            text = "stageid " + " ".join(args)
            try:
                command, ctx = parsed(args)
            except click.ClickException as exc:
                failures.append(f"{text}: does not parse: {exc.format_message()}")
                continue
            absent = [f for f in input_files(ctx) if not Path(f).exists()]
            if help_path == () and absent:
                failures.append(f"{text}: the main help's chain does not write {absent}")
            if command in PARSE_ONLY:
                continue
            code, out, err = run_main(*args, cwd=tmp_path)
            if absent:
                missing.append(text)
                if code != 2 or not any(f in err for f in absent):
                    failures.append(f"{text}: expected exit 2 naming one of {absent}; got {code}: {err.strip()}")
            elif code != 0:
                failures.append(f"{text}: exit {code}: {err.strip()}")
            else:
                ran.append(text)
    assert not failures, "\n".join(failures)
    # the chain of the main help alone is 11 commands; the commands' own examples add more
    assert len(ran) > 11, ran


@pytest.mark.parametrize(
    ("epilog", "expected"),
    [
        ("  stageid a b  # note\n  text\n", [["a", "b"]]),
        ("  stageid a \\\n      --x 1   # note\n", [["a", "--x", "1"]]),
    ],
)
def test_example_lines_reads_comments_and_continuations(epilog, expected):
    assert example_lines(epilog) == expected
