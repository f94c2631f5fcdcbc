"""The classic figure of a best linear approximation: |BLA|, its noise level and total distortion level."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["bla_figure"]


def bla_figure(frd: Any, odd_std: np.ndarray | None = None, even_std: np.ndarray | None = None):
    """Per entry, in dB against frequency: ``|G_BLA|``, its total std (noise and stochastic nonlinear
    distortion, when the FRD has ``total_std``) and its noise std (Pintelon & Schoukens' figure).

    ``odd_std`` / ``even_std`` (the shares of odd / even distortions from the detection lines)
    are drawn as markers when given.  One panel per (output, input); returns the figure (Agg).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    q, m = frd.n_outputs, frd.n_inputs
    fig = Figure(figsize=(4.2 * m, 2.8 * q), layout="constrained")
    FigureCanvasAgg(fig)  # no pyplot state: nothing opens a window
    axes = fig.subplots(q, m, sharex=True, squeeze=False)
    f = frd.freqs

    def db(x: np.ndarray) -> np.ndarray:
        return 20.0 * np.log10(np.maximum(np.abs(x), 1e-300))

    for i, out in enumerate(frd.outputs):
        for j, inp in enumerate(frd.inputs):
            ax = axes[i, j]
            ax.semilogx(f, db(frd.response[:, i, j]), color="k", lw=1.2, label="|BLA|")
            if frd.total_std is not None:
                ax.semilogx(f, db(frd.total_std[:, i, j]), ".", color="tab:red", ms=3, label="total (noise + NL)")
            if frd.std is not None:
                ax.semilogx(f, db(frd.std[:, i, j]), ".", color="tab:green", ms=3, label="noise")
            for share, name, marker in ((odd_std, "odd NL", "v"), (even_std, "even NL", "^")):
                if share is not None:
                    ax.semilogx(f, db(share[:, i, j]), marker, ms=3, mfc="none", label=name)
            ax.set_title(f"{out} from {inp}", fontsize=9)
            ax.set_ylabel("magnitude [dB re 1 output/input]")
        axes[-1, 0].set_xlabel("frequency [Hz]")
    axes[0, 0].legend(fontsize=7)
    return fig
