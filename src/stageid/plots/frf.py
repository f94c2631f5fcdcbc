"""Bode figure of a measured frequency response: +-2 std band, model overlay, coherence panel."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ParameterError

__all__ = ["bode_figure"]


def bode_figure(frd: Any, model: Any = None, ax: Any = None):
    """A :class:`~stageid.frf.FrequencyResponse` as magnitude (with ``|H| +- 2 std`` shaded), phase, and coherence when the FRF has it.

    One column per input, outputs overlaid; ``model`` (anything with
    ``frequency_response(freqs)`` and the same channels) is drawn dashed.  ``ax``: the
    matplotlib axes to draw in instead of a new figure, ``rows x n_inputs`` of them (rows:
    magnitude, phase, and coherence when the FRF has it), as a 2-D array or a flat sequence in
    that order (flat: each input's panels in turn); a single ``Axes`` of a single-input response takes the magnitude panel alone.
    Returns the figure the axes belong to.
    """
    rows = 3 if frd.coherence is not None else 2
    if ax is None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(4.5 * frd.n_inputs, 2.4 * rows), layout="constrained")
        FigureCanvasAgg(fig)  # no pyplot state: nothing opens a window
        axes = fig.subplots(rows, frd.n_inputs, sharex=True, squeeze=False)
    else:
        axes = _given_axes(ax, rows, frd.n_inputs)
        fig = axes[0, 0].figure
    f = frd.freqs
    Gm = None if model is None else model.frequency_response(f)
    for j, inp in enumerate(frd.inputs):
        for i, out in enumerate(frd.outputs):
            mag = np.abs(frd.response[:, i, j])
            line = axes[0, j].loglog(f, mag, label=f"{out} (data)")[0]
            if frd.std is not None:
                lo = np.maximum(mag - 2 * frd.std[:, i, j], mag * 1e-3)
                axes[0, j].fill_between(f, lo, mag + 2 * frd.std[:, i, j], color=line.get_color(), alpha=0.25, lw=0)
            if axes.shape[0] > 1:
                axes[1, j].semilogx(f, np.degrees(np.unwrap(np.angle(frd.response[:, i, j]))), color=line.get_color())
            if Gm is not None:
                axes[0, j].loglog(f, np.abs(Gm[:, i, j]), "--", color="k", lw=1, label=f"{out} (model)")
                if axes.shape[0] > 1:
                    axes[1, j].semilogx(f, np.degrees(np.unwrap(np.angle(Gm[:, i, j]))), "--", color="k", lw=1)
        axes[0, j].set_title(f"from {inp}")
        axes[0, j].set_ylabel("magnitude")
        if axes.shape[0] > 1:
            axes[1, j].set_ylabel("phase [deg]")
        if frd.coherence is not None and axes.shape[0] > 2:
            for i, out in enumerate(frd.outputs):
                axes[2, j].semilogx(f, frd.coherence[:, i], label=out)
            axes[2, j].set_ylim(0, 1.05)
            axes[2, j].set_ylabel("coherence")
        axes[-1, j].set_xlabel("frequency [Hz]")
        axes[0, j].legend(fontsize=7)
    return fig


def _given_axes(ax: Any, rows: int, n_inputs: int) -> np.ndarray:
    """The caller's axes as a (rows, n_inputs) grid; one Axes of a one-input response: (1, 1)."""
    grid = np.asarray(ax, dtype=object)
    if grid.ndim == 0 and n_inputs == 1:
        return grid.reshape(1, 1)
    if grid.size != rows * n_inputs:
        raise ParameterError(
            f"`ax` must hold {rows} x {n_inputs} axes (magnitude, phase{', coherence' if rows == 3 else ''} "
            f"per input); got {grid.size}."
        )
    return grid.reshape(n_inputs, rows).T if grid.ndim == 1 else grid.reshape(rows, n_inputs)
