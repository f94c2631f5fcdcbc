"""The ``stageid`` command line: the only part of stageid that prints or exits.

Every command is a click command in its own module of this package, registered below.
Bad input of any kind ends with exit code 2 and exactly one line on stderr; ``--debug``
shows the traceback instead.
"""

from __future__ import annotations

import importlib
import sys

import click

from .._errors import StageIdError

EXAMPLES = """
\b
Examples:
  stageid plants p558 -o p558.json                  # a reference stage's model
  stageid plants p558 --experiment chirp -o exp.csv # a simulated experiment
  stageid simulate p558.json exp.csv -o sim.csv     # model response to a record
  stageid freqresp p558.json --fmin 1 --fmax 200 --n 300 -o fr.csv
  stageid signal chirp --f0 1 --f1 100 --duration 10 --dt 0.002 -o u.csv
  stageid identify statespace exp.csv --inputs Z,Rx,Ry --outputs z,rx,ry -o model.json
  stageid export c hyst.json --prefix comp --inverse -o build/   # C99 compensator: build/comp.h, .c
"""

# (module, attribute, parent group): each command lives in its own module.
_COMMANDS: list[tuple[str, str, str]] = [
    ("stageid.cli.lti", "simulate_command", "cli"),
    ("stageid.cli.lti", "freqresp_command", "cli"),
    ("stageid.cli.identify_hysteresis", "identify", "identify"),
    ("stageid.cli.compensate", "cli", "cli"),
    ("stageid.cli.signal", "signal_command", "cli"),
    ("stageid.cli.plants", "plants_command", "cli"),
    ("stageid.cli.report", "report_command", "cli"),
    ("stageid.cli.demo", "demo_command", "cli"),
    ("stageid.cli.identify_statespace", "statespace_command", "identify"),
    ("stageid.cli.identify_closedloop", "closedloop_command", "identify"),
    ("stageid.cli.export", "export_group", "cli"),
]


@click.group(epilog=EXAMPLES, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="stageid")
@click.option("--debug", is_flag=True, help="Show full tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """stageid: identify and compensate precision positioning stages."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


@cli.group(
    epilog="""
\b
Examples:
  stageid identify statespace x.csv y.csv --inputs Z,Rx,Ry --outputs z,rx,ry -o model.json
  stageid identify closed-loop ex.csv ey.csv --references rx,ry --outputs x,y --controller K.json -o G.json
  stageid identify hysteresis forc.csv --input V --output y --model modified-pi -o hyst.json
"""
)
def identify() -> None:
    """Identify a model from measured records."""


_GROUPS = {"cli": cli, "identify": identify}


def _register() -> None:
    for module, attr, group in _COMMANDS:
        command = getattr(importlib.import_module(module), attr)
        _GROUPS[group].add_command(command)


_register()


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``stageid`` script; returns the exit code."""
    args = sys.argv[1:] if argv is None else argv
    debug = "--debug" in args
    try:
        cli.main(args=args, prog_name="stageid", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code or 0)
    except click.exceptions.Abort:
        click.echo("stageid: aborted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(f"stageid: error: {_one_line(exc.format_message())}", err=True)
        return 2
    except StageIdError as exc:
        if debug:
            raise
        click.echo(f"stageid: error: {_one_line(str(exc))}", err=True)
        return 2
    except (OSError, MemoryError) as exc:
        if debug:
            raise
        click.echo(f"stageid: error: {_one_line(str(exc) or type(exc).__name__)}", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("stageid: interrupted", err=True)
        return 130
    except Exception as exc:  # a bug: still one line, with a hint how to see more
        if debug:
            raise
        click.echo(
            f"stageid: internal error: {type(exc).__name__}: {_one_line(str(exc))} (rerun with --debug for details)",
            err=True,
        )
        return 3
    return 0


def _one_line(text: str) -> str:
    return " ".join(text.split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
