"""The report of a model fitted to a measured frequency response (``stageid identify frd --report``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .html import Report
from .modes import modal_section
from .provenance import percent_text, settings_section

__all__ = ["frd_fit_report", "frf_caption"]


def frf_caption(frd: Any, source: str = "Measured", fit_band: tuple[float, float] | None = None) -> str:
    """The caption of :meth:`~stageid.frf.FrequencyResponse.plot`, saying what is drawn and what
    the data lack (no std: no band; no coherence: no coherence panel), so it promises nothing
    the figure does not show."""
    parts = [f"{source} frequency response ({frd.freqs[0]:.3g}-{frd.freqs[-1]:.3g} Hz, {frd.n_freqs} lines)"]
    parts.append(
        "shaded: +-2 std of the measurement (where the shading reaches the bottom of the axis, 2 std "
        "exceeds |H|: that entry is not known to better than its own size)"
        if frd.std is not None
        else "no band: the data give no std"
    )
    parts.append(
        "bottom: multiple coherence of each output (set by its largest entry, so a small coupling can "
        "carry a wide band beside a coherence near 1)"
        if frd.coherence is not None
        else "no coherence panel: the data give no coherence"
    )
    if fit_band is not None:
        lo, hi = fit_band
        parts.append(f"grey: outside the fitted band {lo:.4g}-{hi:.4g} Hz (drawn, not fitted)")
    return "; ".join(parts) + "."


def frd_fit_report(
    frd: Any, result: Any, settings: Mapping[str, Any], command: str | None = None
) -> tuple[Report, dict[str, Any]]:
    """Command and settings, the whole measured FRF with the fitted band marked and the model, the
    error per input column in % of its peak (as the command line prints it), the model's modes,
    its uncertainty and, for ``order='auto'``, the order selection.

    ``frd`` is the whole measured response (the report shows the lines outside the fit greyed);
    ``result`` an :class:`~stageid.frf.FRDResult`.  Returns the report and its metrics.
    """
    report = Report(title="identify frd: state-space model fitted to a measured frequency response")
    metrics: dict[str, Any] = {}
    settings_section(report, settings, command)
    report.section("Measured frequency response and identified model")
    report.figure(frd.plot(model=result.model, fit_band=result.band), frf_caption(frd, fit_band=result.band))
    if frd.total_std is not None:
        from ..frf.bla_figure import bla_figure

        report.figure(
            bla_figure(frd),
            "Best linear approximation: |BLA| [dB of output/input], total distortion level (red; the fit's "
            "weights) and noise level (green).",
        )
    lo, hi = result.band
    report.table(
        ["input", "max |model - measured| [% of column peak]"],
        [[name, percent_text(e)] for name, e in zip(result.model.inputs, result.column_errors)],
        caption=f"Model against the measured response over the fitted band {lo:.4g}-{hi:.4g} Hz",
    )
    for name, e in zip(result.model.inputs, result.column_errors):
        metrics[f"column_error_percent/{name}"] = float(100 * e)
    modal_section(report, metrics, result.model)
    _uncertainty(report, metrics, result)
    if result.order_errors:
        report.section("Order selection (held-out frequencies)", level=3)
        report.table(["order", "held-out RMS error"], [[n, e] for n, e in result.order_errors])
    metrics |= {
        "order": result.order,
        "delay": result.delay,
        "weight": result.weight,
        "band_hz": list(result.band),
        "column_errors": [float(e) for e in result.column_errors],
        "stable": bool(result.model.is_stable()),
    }
    report.unit("delay", "samples")
    report.unit("column_errors", "1 (max |model - measured| / column peak)")
    return report, metrics


def _uncertainty(report: Report, metrics: dict[str, Any], result: Any) -> None:
    """The model's response with its +-2 std band over the fitted band (from the fit's covariance)."""
    from .uncertainty import uncertainty_section

    lo, hi = result.band
    hi = hi if result.model.dt is None else min(hi, 0.5 / result.model.dt)
    f = np.geomspace(lo if lo > 0 else 1e-3 * hi, hi, 300)
    uncertainty_section(
        report, metrics, result.response_uncertainty(f), f"model fitted to the FRF ({result.covariance.noise_source})"
    )
