"""What made a report: the command line, the settings and the stageid version, as its first section.

A report read a week later must say how to make it again; the same record goes into
``metrics.json`` under ``run/`` so a script comparing runs sees the settings beside the numbers.
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
    metrics: dict[str, Any],
    settings: Mapping[str, Any],
    command: str | None = None,
    level: int = 2,
) -> None:
    """A "Command and settings" section: the command line (when run from one), the stageid
    version and one row per setting (the values the fit used, e.g. the order ``auto`` chose).

    Also records them in ``metrics`` as ``run/command``, ``run/version`` and ``run/<setting>``.

    Examples
    --------
    >>> r, m = Report("fit"), {}
    >>> settings_section(r, m, {"order": 16, "band [Hz]": (1.0, 2000.0)}, "stageid identify frd a.csv")
    >>> m["run/order"], m["run/command"]
    ('16', 'stageid identify frd a.csv')
    """
    from .. import __version__

    report.section("Command and settings", level)
    rows = []
    if command:
        rows.append(["command", command])
        metrics["run/command"] = command
    rows.append(["stageid version", __version__])
    metrics["run/version"] = __version__
    for name, value in settings.items():
        text = setting_text(value)
        rows.append([name, text])
        metrics[f"run/{name}"] = text
    report.table(["setting", "value"], rows, caption="How this report was made")
