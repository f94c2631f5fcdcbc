"""Library messages in the command line's words: a parameter ``name=`` becomes its ``--flag``.

The library speaks to Python callers, so a message that tells what to change names the
parameter as in a call: ``give `fmax=` or a smaller `dt=```, ``use `weight='none'```,
``drop `per_channel=True```.  A command-line user has flags instead; :func:`as_flags` is
applied where the CLI prints an error (``stageid.cli.main``), so one message serves both.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

__all__ = ["as_flags"]

# library parameter -> option name, where the command line spells it differently
_RENAMED = {"single": "float"}

# `name=` , `name=value`, `name='value'`: a parameter in a call, inside backticks
_PARAMETER = re.compile(r"`([a-z][a-z0-9_]*)=([^`]*)`")


def as_flags(message: str, renamed: Mapping[str, str] | None = None) -> str:
    """``message`` with each `` `name=value` `` written as ``--name value`` (``True``: the bare flag).

    ``renamed`` maps parameters to the options of one command that spells them differently
    (``identify frd`` takes ``sample_time`` as ``--dt``).

    >>> as_flags("give `fmax=` or a smaller `dt=`; use `weight='none'`; drop `per_channel=True`.")
    'give --fmax or a smaller --dt; use --weight none; drop --per-channel.'
    >>> as_flags("a smaller `sample_time=`", {"sample_time": "dt"})
    'a smaller --dt'
    """
    names = {**_RENAMED, **(renamed or {})}

    def flag(match: re.Match[str]) -> str:
        name, value = match.group(1), match.group(2).strip("'\"")
        option = "--" + names.get(name, name).replace("_", "-")
        return option if value in ("", "True") else f"{option} {value}"

    return _PARAMETER.sub(flag, message)
