"""Figures for LTI models: pole-zero maps, time-domain overlays (the Bode figure is :mod:`.bode`, re-exported)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .bode import bode_figure
from .scale import envelope
from .style import subplots

__all__ = ["bode_figure", "pzmap_figure", "time_overlay_figure"]


def pzmap_figure(
    models: Mapping[str, tuple[np.ndarray, np.ndarray]],
    continuous: bool = True,
    title: str = "",
    hz: bool = False,
):
    """Pole-zero map: ``models`` maps a label to (poles, zeros). Poles are x, zeros are o.

    For discrete maps the unit circle is drawn; ``hz`` divides continuous values by 2 pi.
    """
    fig, ax = subplots(figsize=(6.0, 5.0))
    markers = ["x", "+", "1", "2"]
    scale = 1.0 / (2 * np.pi) if (hz and continuous) else 1.0
    for k, (label, (poles, zeros)) in enumerate(models.items()):
        p = np.asarray(poles) * scale
        z = np.asarray(zeros) * scale
        pts = ax.plot(p.real, p.imag, markers[k % len(markers)], ms=9, mew=1.6, label=f"{label} poles")[0]
        if z.size:
            ax.plot(z.real, z.imag, "o", mfc="none", color=pts.get_color(), ms=7, label=f"{label} zeros")
    if continuous:
        ax.axvline(0.0, color="k", lw=0.8)
        unit = "Hz" if hz else "rad/s"
        ax.set_xlabel(f"real [{unit}]")
        ax.set_ylabel(f"imaginary [{unit}]")
    else:
        th = np.linspace(0, 2 * np.pi, 400)
        ax.plot(np.cos(th), np.sin(th), "k", lw=0.8)
        ax.set_aspect("equal")
        ax.set_xlabel("real")
        ax.set_ylabel("imaginary")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.legend(loc="best")
    if title:
        ax.set_title(title)
    return fig


def time_overlay_figure(
    t: np.ndarray,
    measured: np.ndarray,
    predicted: Mapping[str, np.ndarray],
    names: Sequence[str],
    units: Sequence[str] | None = None,
    title: str = "",
    error_of: str | None = None,
    window: tuple[float, float] | None = None,
):
    """Measured outputs with predictions overlaid, and the prediction error underneath.

    Parameters
    ----------
    t : ndarray of shape (n_samples,) in seconds
    measured : ndarray of shape (n_samples, n_outputs)
    predicted : mapping label -> ndarray of shape (n_samples, n_outputs)
    error_of : label whose error trace is drawn (default: the first)
    window : (t0, t1), optional
        Draw the overlay over this window only (a few periods of a long record, see
        :func:`~stageid.plots.scale.zoom_window`) and the error over the whole record as its
        min-max envelope, the window shaded: a long record of a fast signal drawn whole is a block.
    """
    measured = np.asarray(measured).reshape(len(t), -1)
    n = measured.shape[1]
    units = [u or "output unit" for u in units] if units else ["output unit"] * n
    fig, axes = subplots(
        2,
        n,
        figsize=(4.2 * n + 0.8, 5.2),
        squeeze=False,
        sharex=window is None,
        gridspec_kw={"height_ratios": [2.2, 1.0]},
    )
    key = error_of or next(iter(predicted), None)
    shown = slice(None) if window is None else (t >= window[0]) & (t <= window[1])
    for j in range(n):
        ax = axes[0, j]
        ax.plot(t[shown], measured[shown, j], color="0.2", lw=1.4, label="measured")
        for label, yh in predicted.items():
            ax.plot(t[shown], np.asarray(yh).reshape(len(t), -1)[shown, j], lw=1.0, ls="--", label=label)
        ax.set_ylabel(f"{names[j]} [{units[j]}]")
        ax.set_title(names[j] if window is None else f"{names[j]}, {window[0]:.4g}-{window[1]:.4g} s")
        if key is not None:
            err = measured[:, j] - np.asarray(predicted[key]).reshape(len(t), -1)[:, j]
            _error_trace(axes[1, j], t, err, window)
            axes[1, j].set_ylabel(f"error [{units[j]}]")
        axes[0, j].set_xlabel("time [s]")
        axes[1, j].set_xlabel("time [s]")
    axes[0, 0].legend(loc="best")
    if title:
        fig.suptitle(title)
    return fig


def _error_trace(ax, t: np.ndarray, err: np.ndarray, window: tuple[float, float] | None) -> None:
    """The error over the whole record: a line, or with a window its envelope and the window shaded."""
    if window is None:
        ax.plot(t, err, color="C3", lw=0.9)
        return
    te, lo, hi = envelope(t, err)
    ax.fill_between(te, lo, hi, color="C3", lw=0.5, label="error (min-max per bin)")
    ax.axvspan(*window, color="0.8", zorder=0, label="window above")
    ax.legend(loc="best", fontsize=7)
