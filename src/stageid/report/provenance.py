"""What made a report: the command line, the settings and the stageid version, as its first section.

A report read a week later must say how to make it again.  The record stays in the HTML:
``metrics.json`` keeps numbers only.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .html import Report

__all__ = ["settings_section", "setting_text", "percent_text"]


def percent_text(fraction: float) -> str:
    """A fraction as the command line prints it in %, three significant digits (0.02416 -> ``2.42``).

    >>> percent_text(0.02416)
    '2.42'
    """
    return f"{100 * fraction:.3g}"


def setting_text(value: Any) -> str:
    """A setting as a reader types it: sequences comma-separated, None as ``none``, floats short.

    >>> setting_text((1.0, 2000.0)), setting_text(None), setting_text(4e-05)
    ('1, 2000', 'none', '4e-05')
    """
    if value is None:
        return "none"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return ", ".join(setting_text(v) for v in value)
    return str(value)


def settings_section(
    report: Report,
    settings: Mapping[str, Any],
    command: str | None = None,
    level: int = 2,
) -> None:
    """A "Command and settings" section: the command line (when run from one), the stageid
    version and one row per setting (the values the fit used, e.g. the order ``auto`` chose).

    Examples
    --------
    >>> r = Report("fit")
    >>> settings_section(r, {"order": 16, "band [Hz]": (1.0, 2000.0)}, "stageid identify frd a.csv")
    >>> "<td>1, 2000</td>" in r.to_html()
    True
    """
    from .. import __version__

    report.section("Command and settings", level)
    rows = []
    if command:
        rows.append(["command", command])
    rows.append(["stageid version", __version__])
    rows += [[name, setting_text(value)] for name, value in settings.items()]
    report.table(["setting", "value"], rows, caption="How this report was made")
