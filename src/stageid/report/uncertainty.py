"""Uncertainty of an identified model's frequency response in a report: bands and figures.

Every result's ``response_uncertainty(freqs_hz)`` gives a
:class:`~stageid.frf.FrequencyResponse` whose ``std`` is ``sqrt(E|G_est - G|^2)``; the band
drawn is ``|G| +- N_STD std`` (``|G_est - G| <= 2 std`` holds 98 % of the time for a circular
complex Gaussian error).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .html import Report

__all__ = ["N_STD", "magnitude_band", "uncertainty_section"]

#: Width of the drawn bands in standard deviations.
N_STD = 2.0


def magnitude_band(fr: Any, n_std: float = N_STD) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` magnitudes ``|G| -+ n_std std`` (the lower end kept positive for a log axis)."""
    mag = np.abs(fr.response)
    spread = n_std * fr.std
    return np.maximum(mag - spread, 1e-3 * mag), mag + spread


def uncertainty_section(report: Report, metrics: dict[str, Any], fr: Any, source: str, level: int = 2) -> None:
    """A Bode figure of ``fr`` (a FrequencyResponse with ``std``) with its +-2 std bands, and the
    relative std per entry (median and largest over the frequencies) as a table and metrics."""
    from ..plots import bode_figure

    report.section("Uncertainty of the identified model", level)
    report.figure(
        bode_figure(
            fr.freqs,
            {"model": fr.response},
            fr.inputs,
            fr.outputs,
            bands={"model": magnitude_band(fr)},
            title="Model with +-2 std bands",
        ),
        f"Frequency response of the {source} with +-{N_STD:g} std bands "
        f"(std = sqrt(E|G_est - G|^2); |G_est - G| <= 1.73 std holds 95 % of the time for a circular Gaussian error).",
    )
    rows = []
    mag = np.abs(fr.response)
    rel = fr.std / np.where(mag > 0, mag, np.inf)
    for i, out in enumerate(fr.outputs):
        for j, inp in enumerate(fr.inputs):
            med, top = float(np.median(rel[:, i, j])), float(np.max(rel[:, i, j]))
            rows.append([f"{inp} -> {out}", 100 * med, 100 * top])
            metrics[f"uncertainty/relative_std_median_percent/{out}_{inp}"] = 100 * med
            metrics[f"uncertainty/relative_std_max_percent/{out}_{inp}"] = 100 * top
    report.table(
        ["entry", "median std / |G| [%]", "max std / |G| [%]"],
        rows,
        caption=f"Relative standard deviation over {fr.freqs[0]:.3g}-{fr.freqs[-1]:.3g} Hz",
    )
