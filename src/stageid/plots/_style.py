"""The one way stageid makes figures: matplotlib ``Figure`` objects on an Agg canvas.

No pyplot state is touched (no window, nothing to close, safe in servers and threads);
save a figure with ``fig.savefig(path)``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["figure", "subplots"]

_STYLE = {"font.size": 10, "axes.grid": True, "grid.alpha": 0.3, "axes.titlesize": 10, "legend.fontsize": 8}


def figure(figsize: tuple[float, float], layout: str | None = None) -> Any:
    """An empty figure of ``figsize`` inches, attached to an Agg canvas, in stageid's style."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    with matplotlib.rc_context(_STYLE):
        fig = Figure(figsize=figsize, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def subplots(nrows: int = 1, ncols: int = 1, figsize: tuple[float, float] = (6.4, 4.8), **kwargs: Any) -> tuple[Any, Any]:
    """``(figure, axes)`` like ``pyplot.subplots``, with the constrained layout, without pyplot."""
    import matplotlib

    fig = figure(figsize, layout="constrained")
    with matplotlib.rc_context(_STYLE):
        axes = fig.subplots(nrows, ncols, **kwargs)
    return fig, axes
