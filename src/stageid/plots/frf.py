"""Bode figure of a measured frequency response: +-2 std band, model overlay, coherence panel."""

from __future__ import annotations

from typing import Any

import numpy as np

from .style import axes_grid

__all__ = ["bode_figure"]


def bode_figure(frd: Any, model: Any = None, ax: Any = None):
    """A :class:`~stageid.frf.FrequencyResponse` as magnitude (with ``|H| +- 2 std`` shaded), phase, and coherence when the FRF has it.

    One column per input, outputs overlaid; ``model`` (anything with
    ``frequency_response(freqs)`` and the same channels) is drawn dashed.  ``ax``: the axes
    to draw in instead of a new figure (see :func:`~stageid.plots.style.axes_grid`).  Returns
    the figure.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = 3 if frd.coherence is not None else 2
    if ax is not None:  # the caller's axes: magnitude, phase (and coherence) rows by inputs
        axes = axes_grid(ax, rows, frd.n_inputs)
        fig = axes[0, 0].figure
    else:
        fig = Figure(figsize=(4.5 * frd.n_inputs, 2.4 * rows), layout="constrained")
        FigureCanvasAgg(fig)  # no pyplot state: nothing opens a window
        axes = fig.subplots(rows, frd.n_inputs, sharex=True, squeeze=False)
    f = frd.freqs
    Gm = None if model is None else model.frequency_response(f)
    for j, inp in enumerate(frd.inputs):
        for i, out in enumerate(frd.outputs):
            mag = np.abs(frd.response[:, i, j])
            line = axes[0, j].loglog(f, mag, label=f"{out} (data)")[0]
            if frd.std is not None:
                lo = np.maximum(mag - 2 * frd.std[:, i, j], mag * 1e-3)
                axes[0, j].fill_between(f, lo, mag + 2 * frd.std[:, i, j], color=line.get_color(), alpha=0.25, lw=0)
            axes[1, j].semilogx(f, np.degrees(np.unwrap(np.angle(frd.response[:, i, j]))), color=line.get_color())
            if Gm is not None:
                axes[0, j].loglog(f, np.abs(Gm[:, i, j]), "--", color="k", lw=1, label=f"{out} (model)")
                axes[1, j].semilogx(f, np.degrees(np.unwrap(np.angle(Gm[:, i, j]))), "--", color="k", lw=1)
        axes[0, j].set_title(f"from {inp}")
        axes[1, j].set_ylabel("phase [deg]")
        axes[0, j].set_ylabel("magnitude")
        if frd.coherence is not None:
            for i, out in enumerate(frd.outputs):
                axes[2, j].semilogx(f, frd.coherence[:, i], label=out)
            axes[2, j].set_ylim(0, 1.05)
            axes[2, j].set_ylabel("coherence")
        axes[-1, j].set_xlabel("frequency [Hz]")
        axes[0, j].legend(fontsize=7)
    return fig
