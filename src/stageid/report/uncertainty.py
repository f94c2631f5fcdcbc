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

__all__ = ["N_STD", "LOOP_N_STD", "magnitude_band", "uncertainty_section", "loop_band_figure"]

#: Width of the drawn bands in standard deviations.
N_STD = 2.0
#: Width of a hysteresis loop's band (the output's error is real: 1.96 std covers 95 %).
LOOP_N_STD = 1.96


def magnitude_band(fr: Any, n_std: float = N_STD) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` magnitudes ``|G| -+ n_std std`` (the lower end kept positive for a log axis)."""
    mag = np.abs(fr.response)
    spread = n_std * fr.std
    return np.maximum(mag - spread, 1e-3 * mag), mag + spread


def uncertainty_section(
    report: Report,
    metrics: dict[str, Any],
    fr: Any,
    source: str,
    level: int = 2,
    input_units: tuple[str, ...] = (),
    output_units: tuple[str, ...] = (),
) -> None:
    """A Bode figure of ``fr`` (a FrequencyResponse with ``std``) with its +-2 std bands (magnitudes
    in the channels' units when given), and the relative std per entry (median and largest over
    the frequencies) as a table and metrics."""
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
            band_label=f"+-{N_STD:g} std",
            input_units=input_units,
            output_units=output_units,
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


def loop_band_figure(
    u: np.ndarray,
    y: np.ndarray,
    y_hat: np.ndarray,
    std: np.ndarray,
    time: np.ndarray,
    labels: tuple[str, str],
    y_range: float,
) -> Any:
    """A hysteresis model's loop with the band the weights' uncertainty puts on it.

    Left: measured loop, the model's loop and its ``+-LOOP_N_STD std`` edges; right: the error
    ``y - y_hat`` in % of ``y_range`` (the output's own unit when the range is 0) inside the
    shaded band; a long record of a fast input in a window of a few periods beside the whole
    record's envelope (:func:`~stageid.plots.hysteresis.loop_error_figure`).  ``std`` is the
    simulated output's standard deviation (:meth:`~stageid.hysteresis.WeightUncertainty.output_band`).
    """
    from ..plots.hysteresis import loop_error_figure

    return loop_error_figure(
        time,
        u,
        y,
        y_hat,
        labels,
        "error [% of range]" if y_range > 0 else "error",
        scale=100.0 / y_range if y_range > 0 else 1.0,
        band=LOOP_N_STD * np.asarray(std, dtype=float),
        band_label=f"+-{LOOP_N_STD:g} std (weights)",
    )
