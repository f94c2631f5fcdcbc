"""Figures of hysteresis modelling and compensation (the letter's Figs. 4-8 and 10-12); Agg-safe.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (no window,
no global state); save it with ``fig.savefig(path)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .style import subplots

__all__ = ["loop_figure", "model_errors_figure", "tracking_figure"]


def _figure(nrows: int, ncols: int, size: tuple[float, float]):
    return subplots(nrows, ncols, figsize=size, squeeze=False)


def _flat(a: Any) -> np.ndarray:
    return np.asarray(a, dtype=float).reshape(-1)


def loop_figure(
    u: Any, curves: Mapping[str, Any], xlabel: str = "input [V]", ylabel: str = "output [um]", title: str = ""
) -> Any:
    """Input-output loops of several outputs against one input (Figs. 5-7).

    Parameters
    ----------
    u : array_like of shape (n_samples,) or (n_samples, 1)
    curves : mapping of label to array_like of shape (n_samples,) or (n_samples, 1)
    xlabel, ylabel, title : str

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.plots.hysteresis import loop_figure
    >>> u = np.sin(np.linspace(0, 6, 100))
    >>> fig = loop_figure(u, {"measured": u ** 3})
    >>> len(fig.axes)
    1
    """
    fig, axes = _figure(1, 1, (5.0, 4.0))
    ax = axes[0, 0]
    x = _flat(u)
    for label, y in curves.items():
        ax.plot(x, _flat(y), lw=0.8, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.legend()
    return fig


def model_errors_figure(
    time: Any, errors: Mapping[str, Any], ylabel: str = "modelling error [um]", title: str = ""
) -> Any:
    """Modelling-error traces of several models over time (Fig. 8)."""
    fig, axes = _figure(1, 1, (7.0, 3.2))
    ax = axes[0, 0]
    t = _flat(time)
    for label, e in errors.items():
        ax.plot(t, _flat(e), lw=0.7, label=label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.legend()
    return fig


def tracking_figure(time: Any, reference: Any, output: Any, title: str = "", unit: str = "um") -> Any:
    """Desired and real outputs with the error (a) and the hysteresis curve (b), as Figs. 10-12.

    Parameters
    ----------
    time, reference, output : array_like of shape (n_samples,)
    title : str
    unit : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, axes = _figure(1, 2, (10.0, 3.8))
    t, r, y = _flat(time), _flat(reference), _flat(output)
    ax = axes[0, 0]
    ax.plot(t, r, lw=0.9, label="desired")
    ax.plot(t, y, lw=0.9, label="real")
    ax.plot(t, y - r, lw=0.8, label="error")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"displacement [{unit}]")
    ax.set_title("(a) " + title if title else "(a)")
    ax.legend()
    ax = axes[0, 1]
    ax.plot(r, y, lw=0.9)
    lo, hi = float(min(r.min(), y.min())), float(max(r.max(), y.max()))
    ax.plot([lo, hi], [lo, hi], "k--", lw=0.6)
    ax.set_xlabel(f"desired [{unit}]")
    ax.set_ylabel(f"real [{unit}]")
    ax.set_title("(b) hysteresis curve")
    return fig
