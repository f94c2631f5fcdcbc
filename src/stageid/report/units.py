"""The unit of every number in ``metrics.json``: the ``units`` map written beside the metrics.

Metric keys already carry their unit in their name (``fit_percent/<record>/<output>``,
``modes/frequency_hz``, ``unstable_poles_rad_s``); :func:`metric_units` reads it from there
with one table of name parts, so a script reading ``metrics.json`` finds ``units[key]`` instead
of parsing names.  A report adds what a name cannot say (a gain in the records' units) with
:meth:`stageid.report.Report.unit`.

Keys of nested metrics (a validation summary) are their paths joined with ``/``
(``outputs/y/whiteness/statistic``; list elements by index).  A number whose name matches no
rule is left out of the map: its unit is not known.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

__all__ = ["UNIT_RULES", "metric_unit", "metric_units", "numeric_paths"]

#: ``(how a name part matches, the part, the unit)``, the first match wins; tried on the key's
#: parts from the last to the first, so ``fit_percent/ident.csv/y`` is read at ``fit_percent``.
UNIT_RULES: tuple[tuple[str, str, str], ...] = (
    ("contains", "percent_range", "% of the output's range"),
    ("contains", "percent_fsr", "% of the full-scale range"),
    ("contains", "half_width_percent", "% of the output's range"),
    ("contains", "error_inside_percent", "% of samples"),
    ("endswith", "_percent", "%"),
    ("contains", "_percent_", "%"),
    ("endswith", "_rad_s", "rad/s"),
    ("endswith", "_hz", "Hz"),
    ("equals", "seconds", "s"),
    ("endswith", "_seconds", "s"),
    ("equals", "nrmse", "RMS error / output range (1 = 100 %)"),
    ("equals", "damping", "1 (damping ratio)"),
    ("equals", "statistic", "1 (chi-square statistic)"),
    ("equals", "threshold", "1 (chi-square statistic)"),
    ("equals", "alpha", "1 (test level)"),
    ("equals", "p_value", "1 (probability)"),
    ("equals", "correlations", "1 (normalised correlation)"),
    ("equals", "max_abs", "1 (normalised correlation)"),
    ("equals", "bound", "1 (normalised correlation)"),
    ("equals", "dof", "degrees of freedom"),
    ("equals", "n_samples", "samples"),
    ("equals", "pass", "true/false"),
    ("equals", "stable", "true/false"),
    ("equals", "checks_passed", "true/false"),
    ("equals", "lags", "samples"),
    ("equals", "max_lag", "samples"),
    ("equals", "horizons", "samples (Hankel horizon)"),
    ("equals", "orders", "states"),
    ("equals", "order", "states"),
    ("endswith", "_order", "states"),
    ("equals", "n_free", "parameters"),
    ("equals", "offset", "output unit"),
    ("endswith", "_2norm", "output unit (2-norm over the record)"),
)


def _matches(part: str, how: str, pattern: str) -> bool:
    name = part.lower()
    if how == "equals":
        return name == pattern
    if how == "endswith":
        return name.endswith(pattern)
    return pattern in name


def metric_unit(key: str) -> str | None:
    """The unit of metric ``key`` by :data:`UNIT_RULES`, or None when no rule reads it.

    >>> metric_unit("fit_percent/ident.csv/y"), metric_unit("modes/frequency_hz"), metric_unit("gain")
    ('%', 'Hz', None)
    >>> metric_unit("loop_band/max_half_width_percent_range/rec")
    "% of the output's range"
    """
    for part in reversed(key.split("/")):
        for how, pattern, unit in UNIT_RULES:
            if _matches(part, how, pattern):
                return unit
    return None


def numeric_paths(metrics: Any, prefix: str = "") -> Iterator[str]:
    """The ``/``-joined path of every number (or non-empty list of numbers, or null) in ``metrics``."""
    if isinstance(metrics, Mapping):
        for key, value in metrics.items():
            yield from numeric_paths(value, f"{prefix}/{key}" if prefix else str(key))
    elif isinstance(metrics, (list, tuple)) and any(isinstance(v, Mapping) for v in metrics):
        for k, value in enumerate(metrics):
            yield from numeric_paths(value, f"{prefix}/{k}")
    elif _numeric(metrics):
        yield prefix


def _numeric(value: Any) -> bool:
    if isinstance(value, (list, tuple)):  # an empty list holds no number to give a unit
        return len(value) > 0 and all(_numeric(v) for v in value)
    return value is None or isinstance(value, (bool, int, float))


def metric_units(metrics: Mapping[str, Any], known: Mapping[str, str] | None = None) -> dict[str, str]:
    """``{path: unit}`` for every number of ``metrics`` whose unit is known (``known`` first).

    >>> metric_units({"fit_percent/r/y": 97.0, "modes/damping": [0.1], "creep/total_gain": 2.0},
    ...              {"creep/total_gain": "um/V"})
    {'fit_percent/r/y': '%', 'modes/damping': '1 (damping ratio)', 'creep/total_gain': 'um/V'}
    """
    known = dict(known or {})
    units = {}
    for path in numeric_paths(metrics):
        unit = known.get(path) or metric_unit(path)
        if unit is not None:
            units[path] = unit
    return units
