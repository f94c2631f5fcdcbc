"""Bode figure of a measured frequency response: +-2 std band, model overlay, coherence panel."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .style import axes_grid

__all__ = ["bode_figure", "N_STD"]

#: Half-width of the shaded band in standard deviations.
N_STD = 2.0


def bode_figure(
    frd: Any,
    model: Any = None,
    fit_band: tuple[float, float] | None = None,
    input_units: Sequence[str] = (),
    output_units: Sequence[str] = (),
    ax: Any = None,
):
    """A :class:`~stageid.frf.FrequencyResponse` as magnitude (with ``|H| +- 2 std`` shaded when the
    FRF has ``std``), phase, and coherence when the FRF has it.

    One column per input, outputs overlaid; ``model`` (anything with
    ``frequency_response(freqs)`` and the same channels) is drawn dashed.  ``fit_band``
    ``(f_low, f_high)`` greys the frequencies a fit left out (they stay drawn).  Every
    magnitude axis is labelled with its unit (``input_units``/``output_units``, else
    ``output/input``) and shows its lines' peak down to a millionth of it, so a band whose
    lower edge ``|H| - 2 std`` is below zero runs to the bottom of the axis instead of to 1e-300.
    The legend names every drawn artist (data, model, std band, coherence, unfitted band).
    ``ax``: the axes to draw in instead of a new figure (see
    :func:`~stageid.plots.style.axes_grid`).  Returns the figure.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .scale import set_log_magnitude

    rows = 3 if frd.coherence is not None else 2
    if ax is not None:  # the caller's axes: magnitude, phase (and coherence) rows by inputs
        axes = axes_grid(ax, rows, frd.n_inputs)
        fig = axes[0, 0].figure
    else:
        fig = Figure(figsize=(4.5 * frd.n_inputs + 0.6, 2.4 * rows + 0.3), layout="constrained")
        FigureCanvasAgg(fig)  # no pyplot state: nothing opens a window
        axes = fig.subplots(rows, frd.n_inputs, sharex=True, squeeze=False)
    Gm = None if model is None else model.frequency_response(frd.freqs)
    for j, inp in enumerate(frd.inputs):
        lines = _draw_column(axes[:, j], frd, j, Gm)
        set_log_magnitude(axes[0, j], lines)
        axes[0, j].set_title(f"from {inp}")
        axes[0, j].set_ylabel(_magnitude_label(output_units, input_units[j] if j < len(input_units) else ""))
        axes[1, j].set_ylabel("phase [deg]")
        if fit_band is not None:
            _grey_outside(axes[:, j], frd.freqs, fit_band)
        axes[-1, j].set_xlabel("frequency [Hz]")
    # every column has the same entries: one legend per row, on the first column, out of the way
    for row in axes[:, 0]:
        if row.get_legend_handles_labels()[0]:
            row.legend(fontsize=7, loc="best", ncol=2 if frd.n_outputs > 1 else 1, framealpha=0.7)
    return fig


def _draw_column(axes: Any, frd: Any, j: int, Gm: np.ndarray | None) -> list[np.ndarray]:
    """Magnitude, phase (and coherence) of input ``j``'s column; returns the magnitudes drawn as lines."""
    f = frd.freqs
    lines = []
    for i, out in enumerate(frd.outputs):
        mag = np.abs(frd.response[:, i, j])
        lines.append(mag)
        line = axes[0].loglog(f, mag, label=f"{out} (data)")[0]
        if frd.std is not None:
            spread = N_STD * frd.std[:, i, j]
            # the lower edge of a band wider than |H| is clipped by the axis limits, not here
            lo = np.where(mag - spread > 0, mag - spread, 1e-300)
            axes[0].fill_between(
                f, lo, mag + spread, color=line.get_color(), alpha=0.2, lw=0, label=f"{out} +-{N_STD:g} std"
            )
        axes[1].semilogx(f, np.degrees(np.unwrap(np.angle(frd.response[:, i, j]))), color=line.get_color())
        if Gm is not None:
            lines.append(np.abs(Gm[:, i, j]))
            axes[0].loglog(f, np.abs(Gm[:, i, j]), "--", color="k", lw=1, label="model (dashed)" if i == 0 else None)
            axes[1].semilogx(f, np.degrees(np.unwrap(np.angle(Gm[:, i, j]))), "--", color="k", lw=1)
        if frd.coherence is not None:
            axes[2].semilogx(f, frd.coherence[:, i], color=line.get_color(), label=f"{out} coherence")
    if frd.coherence is not None:
        axes[2].set_ylim(0, 1.05)
        axes[2].set_ylabel("coherence [-]")
    return lines


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


def _magnitude_label(output_units: Sequence[str], input_unit: str) -> str:
    """``|H| [um/V]`` when every output shares a unit, else the unit named generically."""
    from .scale import magnitude_label

    shared = set(output_units)
    return magnitude_label(output_units[0] if len(shared) == 1 else "", input_unit)
