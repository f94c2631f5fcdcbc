"""Parameter text shared by the generators' docstrings, filled in at import.

``stageid signal KIND --help`` reads each generator's numpydoc ``Parameters`` section, so a
parameter that means the same in several generators is described once here and placed in
each docstring by a line holding only ``{key}`` (the way scipy's ``doccer`` fills ``%(key)s``;
braces elsewhere, such as ``{"linear", "exponential"}``, are left alone).
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable
from typing import TypeVar

__all__ = ["PARAMETER_DOCS", "fill_doc"]

F = TypeVar("F", bound=Callable[..., object])

PARAMETER_DOCS: dict[str, str] = {
    "duration": "duration : float\n    Length in seconds; ``round(duration / dt)`` samples at ``t = k dt``.",
    "dt": "dt : float\n    Sample time in seconds.",
    "amplitude": "amplitude : float, default 1.0\n    Peak value about ``offset``, > 0.",
    "offset": "offset : float, default 0.0\n    Centre value.",
    "limits": "limits : (float, float), optional\n    Allowed range ``(lo, hi)`` of the signal.",
    "raises": "SignalError\n    If a parameter is out of range or the signal leaves ``limits``.",
    "decaying": (
        "freq : float\n"
        "    Frequency in Hz, ``0 < freq < 1 / (2 dt)``.\n"
        "n_cycles : int\n"
        "    Number of cycles, >= 2; ``round(n_cycles / (freq dt))`` samples at ``t = k dt``.\n"
        "{dt}\n"
        "amplitude : float, default 1.0\n"
        "    Amplitude of the first cycle (half the full input range), > 0.\n"
        "offset : float, default 0.0\n"
        "    Centre of the input range.\n"
        'decay : {"linear", "exponential"}, default "linear"\n'
        "    Envelope law, see :func:`decay_envelope`.\n"
        "final_fraction : float, optional\n"
        "    Last-cycle amplitude relative to the first, in (0, 1).\n"
        "{limits}"
    ),
}

# a line holding only ``{key}``, indented as the text that replaces it must be
_PLACEHOLDER = re.compile(r"^( *)\{(\w+)\}$", re.MULTILINE)


def _expand(text: str) -> str:
    return _PLACEHOLDER.sub(lambda m: textwrap.indent(_expand(PARAMETER_DOCS[m.group(2)]), m.group(1)), text)


def fill_doc(func: F) -> F:
    """Replace every ``{key}`` line of ``func.__doc__`` by ``PARAMETER_DOCS[key]``; returns ``func``.

    An unknown key raises ``KeyError`` at import, so a misspelt placeholder cannot reach a help text.
    """
    if func.__doc__:
        func.__doc__ = _expand(func.__doc__)
    return func
