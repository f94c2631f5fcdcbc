"""The ``stageid`` command line: the only part of stageid that prints or exits.

Every command is a click command in its own module of this package, registered below.
Bad input of any kind ends with exit code 2 and exactly one line on stderr; ``--debug``
shows the traceback instead.  Every command runs in one output transaction
(:func:`stageid.atomic.transaction`): its files appear together, after everything that can
fail, and what it prints appears after them; warnings become one-line messages.
"""

from __future__ import annotations

import importlib
import sys
import warnings

import click

from .._errors import StageIdError
from .flags import as_flags

EXAMPLES = """
\b
Examples:
  # in order: each reads the files the earlier ones wrote
  stageid plants p558 -o p558.json                       # a reference stage's model
  stageid plants p558 --experiment band-limited -o exp.csv   # a simulated experiment, all inputs
  stageid simulate p558.json exp.csv -o sim.csv          # model response to a record
  stageid freqresp p558.json --fmin 1 --fmax 200 --n 300 -o fr.csv
  stageid signal chirp --f0 1 --f1 100 --duration 10 --dt 0.002 -o u.csv
  stageid identify statespace exp.csv --inputs Z,Rx,Ry --outputs z,rx,ry -o model.json
  stageid validate model.json exp.csv                    # fit and residual tests per record
  stageid export c model.json --prefix plant -o build/   # C99 model: build/plant.h, .c
  stageid plants p558 --experiment random-z -o z.csv
  stageid frf z.csv --inputs Z --outputs z -o frf.csv    # measured FRF + coherence + std
  stageid identify frd frf.csv --order auto --dt 0.002 -o frd.json
  stageid serve .                                        # the same steps in the browser
"""

# (name, module, attribute, parent group): each command lives in its own module, imported when
# the command runs or a help text lists it, so one command does not pay for the others' imports.
_COMMANDS: list[tuple[str, str, str, str]] = [
    ("simulate", "stageid.cli.lti", "simulate_command", "cli"),
    ("freqresp", "stageid.cli.lti", "freqresp_command", "cli"),
    ("hysteresis", "stageid.cli.identify_hysteresis", "identify", "identify"),
    ("compensate", "stageid.cli.compensate", "cli", "cli"),
    ("signal", "stageid.cli.signal", "signal_command", "cli"),
    ("plants", "stageid.cli.plants", "plants_command", "cli"),
    ("report", "stageid.cli.report", "report_command", "cli"),
    ("demo", "stageid.cli.demo", "demo_command", "cli"),
    ("statespace", "stageid.cli.identify_statespace", "statespace_command", "identify"),
    ("closed-loop", "stageid.cli.identify_closedloop", "closedloop_command", "identify"),
    ("closedloop", "stageid.cli.identify_closedloop", "closedloop_command", "identify"),  # both spellings
    ("export", "stageid.cli.export", "export_group", "cli"),
    ("frf", "stageid.cli.frf", "frf_command", "cli"),
    ("frd", "stageid.cli.identify_frd", "frd_command", "identify"),
    ("validate", "stageid.cli.validate", "validate_command", "cli"),
    ("batch", "stageid.cli.batch", "batch_command", "cli"),
    ("serve", "stageid.cli.serve", "serve_command", "cli"),
]


class _LazyGroup(click.Group):
    """A group whose sub-commands in :data:`_COMMANDS` load on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*self.commands, *(name for name, _, _, group in _COMMANDS if group == self.name)})

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in self.commands:
            for entry, module, attr, group in _COMMANDS:
                if (entry, group) == (name, self.name):
                    self.add_command(getattr(importlib.import_module(module), attr), name=name)
        return self.commands.get(name)


class _Interrupted(Exception):
    """Ctrl-C, carried past click (which would print an empty line and call it "aborted")."""


class _RootGroup(_LazyGroup):
    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise _Interrupted() from exc


@click.group(
    cls=_RootGroup, epilog=EXAMPLES, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100}
)
@click.version_option(package_name="stageid")
@click.option("--debug", is_flag=True, help="Show full tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """stageid: identify and compensate precision positioning stages."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


@cli.group(
    cls=_LazyGroup,
    epilog="""
\b
Examples:
  stageid identify statespace x.csv y.csv --inputs Z,Rx,Ry --outputs z,rx,ry -o model.json
  stageid identify closed-loop ex.csv ey.csv --references rx,ry --outputs x,y --controller K.json -o G.json
  stageid identify hysteresis forc.csv --input V --output y --model modified-pi -o hyst.json
  stageid identify frd frf.csv --order auto --dt 0.0002 -o model.json
""",
)
def identify() -> None:
    """Identify a model from measured records."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``stageid`` script; returns the exit code.

    Exit codes: 0 success; 1 some jobs of a batch failed (``stageid batch``); 2 bad input,
    settings or resources (one line on stderr, no output written); 130 interrupted; 3 a bug in stageid (one line; ``--debug`` shows the traceback).
    """
    from ..atomic import transaction
    from ._common import flush_messages

    args = sys.argv[1:] if argv is None else argv
    debug = "--debug" in args
    flush_messages(print_them=False)  # nothing left over from an earlier call in this process
    try:
        with warnings.catch_warnings(), transaction():
            warnings.showwarning = _warning_as_message
            warnings.simplefilter("default")
            warnings.filterwarnings("ignore", category=RuntimeWarning)  # numpy's floating-point notes
            # the arguments ride along so a report can record the command that made it
            code = cli.main(args=args, prog_name="stageid", standalone_mode=False, obj={"argv": list(args)})
    except click.exceptions.Exit as exc:
        flush_messages()
        return int(exc.exit_code or 0)
    except BaseException as exc:
        flush_messages(print_them=False)
        code, text = _failure(exc)
        if code is None or (debug and code != 130 and not isinstance(exc, click.ClickException)):
            raise
        click.echo(text, err=True)
        return code
    flush_messages()
    return code if type(code) is int else 0  # ctx.exit(n): a command's own exit code (batch: 1)


def _failure(exc: BaseException) -> tuple[int | None, str]:
    """The exit code and the one stderr line for an exception ending a command (None: re-raise)."""
    if _interrupted(exc):
        return 130, "stageid: interrupted"
    if isinstance(exc, click.exceptions.Abort):
        return 130, "stageid: aborted"
    if isinstance(exc, click.ClickException):
        return 2, f"stageid: error: {_one_line(exc.format_message())}"
    if isinstance(exc, StageIdError):  # the library names parameters (`fmax=`); the user typed flags
        return 2, f"stageid: error: {_one_line(as_flags(str(exc)))}"
    if isinstance(exc, (OSError, MemoryError)):
        return 2, f"stageid: error: {_one_line(str(exc) or type(exc).__name__)}"
    if isinstance(exc, Exception):  # a bug: still one line, with a hint how to see more
        return 3, (
            f"stageid: internal error: {type(exc).__name__}: {_one_line(str(exc))} "
            "(rerun with --debug for the traceback and report it at the project's issue tracker)"
        )
    return None, ""


def _interrupted(exc: BaseException) -> bool:
    """True for Ctrl-C, also when a compiled kernel turned it into a ``SystemError``.

    A KeyboardInterrupt raised while numba code runs surfaces as "SystemError: ... returned a
    result with an exception set", holding the KeyboardInterrupt as its cause or context.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _warning_as_message(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one ``stageid: warning: ...`` line, printed after the command succeeded."""
    from ._common import say

    say(f"stageid: warning: {_one_line(str(message))}", err=True)


def _one_line(text: str) -> str:
    return " ".join(text.split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
