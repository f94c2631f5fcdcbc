"""Matplotlib set-up shared by every figure: Agg backend, readable sizes."""

from __future__ import annotations

from typing import Any


def pyplot() -> Any:
    """Import pyplot on the Agg backend (no display needed) with stageid's style."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    plt.rcParams.update({
        "figure.dpi": 100,
        "font.size": 10,
        "axes.grid": True,
        "grid.alpha": 0.3,
        "axes.titlesize": 10,
        "legend.fontsize": 8,
    })
    return plt


def new_figure(plt, *args, **kwargs):
    """``plt.subplots`` with the constrained layout set on this figure only."""
    return plt.subplots(*args, layout="constrained", **kwargs)
