"""The one way stageid makes figures: matplotlib ``Figure`` objects on an Agg canvas.

No pyplot state is touched (no window, nothing to close, safe in servers and threads);
save a figure with ``fig.savefig(path)``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["figure", "subplots", "positive", "loglog", "axes_grid"]

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


def positive(values: Any) -> Any:
    """``values`` as floats with every entry that is not > 0 (or not finite) replaced by NaN.

    A log axis cannot show zero or negative values; matplotlib would drop them with a
    multi-line warning (or warn that nothing can be log-scaled).  NaN leaves a gap instead.
    """
    import numpy as np

    v = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(v) & (v > 0), v, np.nan)


def loglog(ax: Any, x: Any, y: Any, *args: Any, **kwargs: Any) -> Any:
    """``ax.loglog(x, y, ...)`` with non-positive ``x``/``y`` left out (no matplotlib warnings).

    When nothing is left to draw (e.g. the response of an input that did not move is exactly
    zero) the axis says so in its centre instead.  Returns the Line2D drawn.
    """
    import numpy as np

    xs, ys = positive(x), positive(y)
    (line,) = ax.loglog(xs, ys, *args, **kwargs)
    if not np.any(np.isfinite(xs) & np.isfinite(ys)) and not getattr(ax, "_stageid_zero_note", False):
        ax.text(
            0.5,
            0.5,
            "zero response\n(nothing to draw on a log axis)",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=8,
            color="0.35",
        )
        ax._stageid_zero_note = True
    return line


def subplots(
    nrows: int = 1, ncols: int = 1, figsize: tuple[float, float] = (6.4, 4.8), **kwargs: Any
) -> tuple[Any, Any]:
    """``(figure, axes)`` like ``pyplot.subplots``, with the constrained layout, without pyplot."""
    import matplotlib

    fig = figure(figsize, layout="constrained")
    with matplotlib.rc_context(_STYLE):
        axes = fig.subplots(nrows, ncols, **kwargs)
    return fig, axes


def axes_grid(ax: Any, rows: int, cols: int) -> Any:
    """The caller's matplotlib axes as a ``(rows, cols)`` object array, for figures drawn into them.

    ``ax`` is a 2-D array of that shape, or a flat sequence of ``rows * cols`` axes giving each
    column's panels in turn (one ``Axes`` when the figure has one panel).  Any other count is a
    :class:`~stageid.ParameterError`.
    """
    import numpy as np

    from .._errors import ParameterError

    grid = np.asarray(ax, dtype=object)
    if grid.size != rows * cols:
        raise ParameterError(f"`ax` must hold {rows} x {cols} axes (rows of panels by columns); got {grid.size}.")
    return grid.reshape(rows, cols) if grid.ndim == 2 else grid.reshape(cols, rows).T
