"""Figures of measured records before any model: the signals over time and their spectra."""

from __future__ import annotations

from typing import Any

import numpy as np

from .style import loglog, subplots

__all__ = ["record_figure", "spectrum_figure"]

_MAX_POINTS = 2000  # about two points per pixel of the figure; more only slows the page


def _channels(exp: Any) -> list[tuple[str, str, np.ndarray, str]]:
    names = list(exp.input_names) + list(exp.output_names)
    kinds = ["input"] * exp.n_inputs + ["output"] * exp.n_outputs
    units = list(exp.input_units) + list(exp.output_units)
    values = np.hstack([exp.u, exp.y])
    return [(kinds[k], names[k], values[:, k], units[k] or f"{kinds[k]} unit") for k in range(len(names))]


def record_figure(exp: Any, title: str = "") -> Any:
    """Every input and output of an :class:`~stageid.data.Experiment` against time, one row each.

    A record longer than two thousand samples is drawn as its min-max envelope over a thousand
    bins (:func:`~stageid.plots.scale.envelope`): every-k-th-sample decimation would alias a fast
    signal into a slow one.
    """
    from .scale import envelope

    channels = _channels(exp)
    fig, axes = subplots(len(channels), 1, figsize=(7.5, 1.4 + 1.3 * len(channels)), squeeze=False, sharex=True)
    for ax, (kind, name, values, unit) in zip(axes[:, 0], channels):
        color = "C0" if kind == "input" else "C1"
        if exp.n_samples > _MAX_POINTS:
            t, lo, hi = envelope(exp.time, values, _MAX_POINTS // 2)
            ax.fill_between(t, lo, hi, color=color, lw=0.5)
        else:
            ax.plot(exp.time, values, lw=0.8, color=color)
        ax.set_ylabel(f"{name} ({kind})\n[{unit}]")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    return fig


def spectrum_figure(exp: Any, segment: int | None = None, title: str = "") -> Any:
    """Power spectral densities (Welch, Hann window, half overlap) of every channel.

    ``segment`` defaults to a quarter of the record, at most 4096 samples, so the lowest lines
    are resolved and the estimate still averages a few segments.
    """
    from scipy.signal import welch

    n = exp.n_samples
    nper = segment or max(8, min(4096, n // 4))
    fig, ax = subplots(1, 1, figsize=(7.5, 3.6))
    for kind, name, values, _ in _channels(exp):
        f, p = welch(values, fs=1.0 / exp.dt, nperseg=min(nper, n))
        loglog(ax, f[1:], p[1:], lw=0.9, ls="-" if kind == "output" else "--", label=f"{name} ({kind})")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("PSD [unit^2/Hz]")
    ax.legend(loc="best")
    if title:
        ax.set_title(title)
    return fig
