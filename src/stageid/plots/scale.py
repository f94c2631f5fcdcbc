"""Readable axes for every figure: magnitude units, log limits clipped to a dynamic range, zoom windows.

A log magnitude axis autoscaled to a response that touches zero (a band whose lower edge is
``|G| - 2 std < 0``, an entry that is exactly zero) stretches to 1e-300 and flattens every
line; these helpers give each magnitude axis a unit in its label and limits from the lines'
peak down to ``peak / DYNAMIC_RANGE``, and say so when an entry lies wholly below.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

__all__ = [
    "DYNAMIC_RANGE",
    "magnitude_unit",
    "magnitude_label",
    "peak",
    "log_limits",
    "set_log_magnitude",
    "zoom_window",
    "dominant_period",
    "envelope",
]

#: Decades a log magnitude axis shows below the peak of its lines (peak / 1e6 at the bottom).
DYNAMIC_RANGE = 1e6


def magnitude_unit(output_unit: str = "", input_unit: str = "") -> str:
    """The unit of a response's magnitude, ``"um/V"``; a missing side is named ``output``/``input``.

    >>> magnitude_unit("um", "V"), magnitude_unit("", ""), magnitude_unit("rad", "N m")
    ('um/V', 'output/input', 'rad/(N m)')
    """
    below = input_unit or "input"
    if any(c in below for c in " /*"):  # "m/N m" would read as (m/N) m
        below = f"({below})"
    return f"{output_unit or 'output'}/{below}"


def magnitude_label(output_unit: str = "", input_unit: str = "") -> str:
    """The y label of a magnitude axis, ``"|G| [um/V]"`` (``"|G| [output/input]"`` when unknown)."""
    return f"|G| [{magnitude_unit(output_unit, input_unit)}]"


def _finite_positive(magnitudes: Iterable[Any]) -> np.ndarray:
    values = [np.abs(np.asarray(m, dtype=float)).ravel() for m in magnitudes]
    flat = np.concatenate(values) if values else np.zeros(0)
    return flat[np.isfinite(flat) & (flat > 0)]


def peak(magnitudes: Iterable[Any]) -> float:
    """The largest finite magnitude of several arrays (0.0 when none is positive)."""
    ok = _finite_positive(magnitudes)
    return float(ok.max()) if ok.size else 0.0


def log_limits(magnitudes: Iterable[Any], dynamic_range: float = DYNAMIC_RANGE) -> tuple[float, float] | None:
    """``(low, high)`` for a log axis showing ``magnitudes`` (arrays of the drawn lines).

    ``high`` is a little above their peak and ``low`` the smallest positive value, but never
    below ``peak / dynamic_range``; None when no value is positive and finite.

    >>> log_limits([np.array([1.0, 1e-320, 0.5])], 1e6)
    (7.943e-07, 1.259)
    """
    ok = _finite_positive(magnitudes)
    if ok.size == 0:
        return None
    top = float(ok.max())
    low = max(float(ok.min()), top / dynamic_range)
    pad = 10**0.1  # a tenth of a decade so the extreme points do not sit on the frame
    return float(f"{low / pad:.4g}"), float(f"{top * pad:.4g}")


def set_log_magnitude(
    ax: Any, magnitudes: Iterable[Any], reference_peak: float | None = None, dynamic_range: float = DYNAMIC_RANGE
) -> bool:
    """Limit a log magnitude axis to its lines' dynamic range; True when the entry is numerically zero.

    ``reference_peak`` is the largest magnitude of the whole response (every entry): an entry
    whose own peak lies below ``reference_peak / dynamic_range`` is drawn on the axis of that
    floor and the panel says ``below <floor> (numerically zero)`` instead of stretching its
    axis down to the rounding error.
    """
    limits = log_limits(magnitudes, dynamic_range)
    floor = None if reference_peak is None or reference_peak <= 0 else reference_peak / dynamic_range
    if floor is not None and (limits is None or limits[1] < floor):
        ax.set_ylim(floor / 10**0.1, reference_peak * 10**0.1)
        if limits is None:  # nothing positive at all: the line drawer has said "zero response"
            return True
        ax.text(
            0.5,
            0.5,
            f"below {floor:.1g} (numerically zero)",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=8,
            color="0.3",
        )
        return True
    if limits is not None:
        ax.set_ylim(*limits)
    return False


def zoom_window(time: Any, period: float, n_periods: float = 3.0) -> tuple[float, float] | None:
    """The last ``n_periods`` periods of a record, ``(t0, t1)``, when the record holds many more
    (more than ``4 n_periods``): a long record of a fast signal drawn whole is a solid block.

    >>> zoom_window(np.arange(0, 5, 1e-4), 0.01)
    (4.9699, 4.9999)
    """
    t = np.asarray(time, dtype=float)
    if t.size < 2 or period <= 0 or t[-1] - t[0] <= 4 * n_periods * period:
        return None
    return float(t[-1] - n_periods * period), float(t[-1])


def dominant_period(values: Any, dt: float) -> float | None:
    """The period [s] of the strongest spectral line of ``values`` (mean removed; DC left out), or
    None for a record too short or flat to have one.

    >>> round(dominant_period(np.sin(2 * np.pi * 100 * np.arange(0, 1, 1e-4)), 1e-4), 6)
    0.01
    """
    x = np.asarray(values, dtype=float).reshape(len(values), -1)[:, 0]
    if x.size < 8 or not np.ptp(x) > 0:
        return None
    spectrum = np.abs(np.fft.rfft(x - x.mean()))
    k = int(np.argmax(spectrum[1:])) + 1
    return float(x.size * dt / k)


def envelope(time: Any, values: Any, n_bins: int = 600) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, low, high)``: the minimum and maximum of ``values`` in ``n_bins`` consecutive bins, so a
    long oscillating trace drawn as a band keeps its extremes (every-k-th-sample decimation would
    alias them away).  A record of at most ``n_bins`` samples comes back as it is.

    >>> t, lo, hi = envelope(np.arange(10.0), np.arange(10.0) % 2, n_bins=2)
    >>> t.tolist(), lo.tolist(), hi.tolist()
    ([0.0, 5.0], [0.0, 0.0], [1.0, 1.0])
    """
    t, x = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    if x.size <= n_bins:
        return t, x, x
    edges = np.linspace(0, x.size, n_bins + 1).astype(int)
    starts = edges[:-1]
    return t[starts], np.minimum.reduceat(x, starts), np.maximum.reduceat(x, starts)
