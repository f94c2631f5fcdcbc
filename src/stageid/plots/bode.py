"""The Bode figure: magnitude and phase of MIMO responses, one panel per entry, with bands.

Every Bode figure of stageid is drawn here: a model's response (reports, the demo, the app), a
measured FRF (:meth:`~stageid.models.frequency_response.FrequencyResponse.plot`, through
:func:`stageid.plots.frf.frf_figure`: its std band, its coherence row, the band a fit left out)
and a result with its uncertainty band.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import scale
from .scale import peak, set_log_magnitude
from .style import axes_grid, loglog, positive, subplots

__all__ = ["bode_figure"]


def bode_figure(
    freqs_hz: np.ndarray,
    responses: Mapping[str, np.ndarray],
    input_names: Sequence[str],
    output_names: Sequence[str],
    bands: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    title: str = "",
    magnitude_unit: str = "",
    phase: bool = True,
    styles: Mapping[str, str] | None = None,
    input_units: Sequence[str] = (),
    output_units: Sequence[str] = (),
    band_label: str = "band",
    coherence: np.ndarray | None = None,
    fit_band: tuple[float, float] | None = None,
    ax: Any = None,
):
    """Bode magnitude (and phase) of several MIMO responses on one grid of subplots.

    Parameters
    ----------
    freqs_hz : ndarray of shape (n_freqs,)
    responses : mapping label -> complex ndarray of shape (n_freqs, n_outputs, n_inputs)
    input_names, output_names : channel names for the subplot titles
    bands : mapping label -> (lower, upper) magnitude arrays of shape (n_freqs, n_outputs, n_inputs),
        drawn as shaded uncertainty bands under the response with the same label.
    phase : bool
        Add a phase row under every magnitude row.
    magnitude_unit : str
        The unit of every entry's magnitude (e.g. ``"um/V"``); by default each entry's unit is
        ``output_units[i]/input_units[j]``, ``output/input`` where a unit is not known.
    styles : mapping label -> matplotlib format string (``"k--"``), optional
    input_units, output_units : sequence of str, optional
        The channels' units.
    band_label : str
        The legend names a band ``"<label> <band_label>"`` (e.g. ``"model +-2 std"``).
    coherence : ndarray of shape (n_freqs, n_outputs), optional
        A last row per input column: the outputs' (multiple) coherence, on 0-1.
    fit_band : (f_low, f_high), optional
        Grey the frequencies outside it on every panel (a fit left them out; they stay drawn).
    ax : matplotlib axes, optional
        Draw in these instead of a new figure: the rows above by input columns, as a 2-D array
        or each column's panels in turn (:func:`~stageid.plots.style.axes_grid`).

    Every magnitude axis is limited to its lines' peak down to ``peak / 1e6``
    (:func:`~stageid.plots.scale.set_log_magnitude`); an entry below a millionth of the
    largest entry's peak says it is numerically zero.

    Returns
    -------
    matplotlib.figure.Figure
    """
    p, m = len(output_names), len(input_names)
    per_output = 2 if phase else 1
    axes = _axes(ax, per_output * p + (coherence is not None), m, phase)
    styles = dict(styles or {})
    for i in range(p):
        for j in range(m):
            axm, axp = axes[per_output * i, j], axes[per_output * i + 1, j] if phase else None
            for label, H in responses.items():
                band = None if not bands or label not in bands else (bands[label][0][:, i, j], bands[label][1][:, i, j])
                style = styles.get(label, "-")
                _draw_entry(axm, axp, freqs_hz, H[:, i, j], band, style, label, f"{label} {band_label}")
            axm.set_title(f"{input_names[j]} → {output_names[i]}")
            unit = magnitude_unit or scale.magnitude_unit(_unit(output_units, i), _unit(input_units, j))
            axm.set_ylabel(f"|G| [{unit}]")
    _limit_magnitudes(axes, responses, p, m, per_output)
    if coherence is not None:
        for j in range(m):
            _coherence_panel(axes[-1, j], freqs_hz, coherence, output_names)
    if fit_band is not None:
        for j in range(m):
            _grey_outside(axes[:, j], freqs_hz, fit_band)
    for a in axes[-1]:
        a.set_xlabel("frequency [Hz]")
    axes[0, 0].legend(loc="best")
    fig = axes[0, 0].figure
    if title:
        fig.suptitle(title)
    return fig


def _axes(ax: Any, rows: int, cols: int, phase: bool) -> np.ndarray:
    """The caller's axes as a (rows, cols) grid, or those of a new figure sized for the grid."""
    if ax is not None:
        return axes_grid(ax, rows, cols)
    size = (3.6 * cols + 1.0, (2.2 if phase else 2.6) * rows + 0.6)
    return subplots(rows, cols, figsize=size, squeeze=False, sharex=True)[1]


def _limit_magnitudes(axes: np.ndarray, responses: Mapping[str, np.ndarray], p: int, m: int, rows: int) -> None:
    """Each magnitude axis from its lines' peak down, not from the bands: a band edge at
    |G| - 2 std <= 0 would reach 1e-300."""
    top = peak(np.abs(H) for H in responses.values())
    for i in range(p):
        for j in range(m):
            mags = [np.abs(H[:, i, j]) for H in responses.values()]
            set_log_magnitude(axes[rows * i, j], mags, reference_peak=top if top > 0 else None)


def _draw_entry(ax, axp, freqs_hz, h, band, style: str, label: str, band_label: str) -> None:
    """One entry of one response: magnitude (with its band, labelled for the legend) and phase."""
    color = style[0] if style[:1].isalpha() else None
    ls = style[1:] if color else style
    line = loglog(ax, freqs_hz, np.abs(h), ls, color=color, label=label, lw=1.3)
    if band is not None:
        upper = positive(band[1])
        ax.fill_between(
            positive(freqs_hz),
            np.fmin(np.maximum(band[0], 1e-300), upper),
            upper,
            color=line.get_color(),
            alpha=0.25,
            lw=0,
            label=band_label,
        )
    if axp is not None:
        axp.semilogx(positive(freqs_hz), np.degrees(np.unwrap(np.angle(h))), ls, color=line.get_color(), lw=1.1)
        axp.set_ylabel("phase [deg]")


def _coherence_panel(ax: Any, freqs_hz: np.ndarray, coherence: np.ndarray, output_names: Sequence[str]) -> None:
    """Every output's coherence on 0-1, one line each, with its legend."""
    for i, out in enumerate(output_names):
        ax.semilogx(positive(freqs_hz), coherence[:, i], lw=1.1, label=f"{out} coherence")
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("coherence [-]")
    ax.legend(fontsize=7, loc="best")


def _grey_outside(axes: Any, freqs: np.ndarray, band: tuple[float, float]) -> None:
    """Shade the frequencies outside ``band`` on every panel of a column (one legend entry)."""
    lo, hi = band
    spans = [(freqs[0], lo), (hi, freqs[-1])]
    for ax in axes:
        first = True
        for a, b in spans:
            if b > a:
                ax.axvspan(a, b, color="0.85", zorder=0, lw=0, label="not fitted" if first and ax is axes[0] else None)
                first = False


def _unit(units: Sequence[str], k: int) -> str:
    return units[k] if k < len(units) else ""
