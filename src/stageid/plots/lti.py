"""Figures for LTI models: Bode magnitude/phase grids, pole-zero maps, time-domain overlays."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .style import loglog, positive, subplots

__all__ = ["bode_figure", "pzmap_figure", "time_overlay_figure"]


def bode_figure(
    freqs_hz: np.ndarray,
    responses: Mapping[str, np.ndarray],
    input_names: Sequence[str],
    output_names: Sequence[str],
    bands: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    title: str = "",
    magnitude_unit: str = "",
    phase: bool = True,
    styles: Mapping[str, str] | None = None,
):
    """Bode magnitude (and phase) of several MIMO responses on one grid of subplots.

    Parameters
    ----------
    freqs_hz : ndarray of shape (n_freqs,)
    responses : mapping label -> complex ndarray of shape (n_freqs, n_outputs, n_inputs)
    input_names, output_names : channel names for the subplot titles
    bands : mapping label -> (lower, upper) magnitude arrays of shape (n_freqs, n_outputs, n_inputs),
        drawn as shaded uncertainty bands under the response with the same label.
    phase : bool
        Add a phase row under every magnitude row.

    Returns
    -------
    matplotlib.figure.Figure
    """
    p, m = len(output_names), len(input_names)
    rows = 2 * p if phase else p
    fig, axes = subplots(
        rows, m, figsize=(3.6 * m + 1.0, (2.2 if phase else 2.6) * rows + 0.6), squeeze=False, sharex=True
    )
    styles = dict(styles or {})
    for label, H in responses.items():
        style = styles.get(label, "-")
        color = style[0] if style[:1].isalpha() else None
        ls = style[1:] if color else style
        for i in range(p):
            for j in range(m):
                ax = axes[2 * i if phase else i, j]
                line = loglog(ax, freqs_hz, np.abs(H[:, i, j]), ls, color=color, label=label, lw=1.3)
                if bands and label in bands:
                    lo, hi = bands[label]
                    upper = positive(hi[:, i, j])
                    ax.fill_between(
                        positive(freqs_hz),
                        np.fmin(np.maximum(lo[:, i, j], 1e-300), upper),
                        upper,
                        color=line.get_color(),
                        alpha=0.25,
                        lw=0,
                    )
                ax.set_title(f"{input_names[j]} → {output_names[i]}")
                if j == 0:
                    ax.set_ylabel(f"|G| {magnitude_unit}".strip())
                if phase:
                    axp = axes[2 * i + 1, j]
                    axp.semilogx(
                        positive(freqs_hz),
                        np.degrees(np.unwrap(np.angle(H[:, i, j]))),
                        ls,
                        color=line.get_color(),
                        lw=1.1,
                    )
                    if j == 0:
                        axp.set_ylabel("phase [deg]")
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    axes[0, 0].legend(loc="best")
    if title:
        fig.suptitle(title)
    return fig


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
):
    """Measured outputs with predictions overlaid, and the prediction error underneath.

    Parameters
    ----------
    t : ndarray of shape (n_samples,) in seconds
    measured : ndarray of shape (n_samples, n_outputs)
    predicted : mapping label -> ndarray of shape (n_samples, n_outputs)
    error_of : label whose error trace is drawn (default: the first)
    """
    measured = np.asarray(measured).reshape(len(t), -1)
    n = measured.shape[1]
    units = list(units) if units else [""] * n
    fig, axes = subplots(
        2, n, figsize=(4.2 * n + 0.8, 5.2), squeeze=False, sharex=True, gridspec_kw={"height_ratios": [2.2, 1.0]}
    )
    key = error_of or next(iter(predicted), None)
    for j in range(n):
        ax = axes[0, j]
        ax.plot(t, measured[:, j], color="0.2", lw=1.4, label="measured")
        for label, yh in predicted.items():
            ax.plot(t, np.asarray(yh).reshape(len(t), -1)[:, j], lw=1.0, ls="--", label=label)
        unit = f" [{units[j]}]" if units[j] else ""
        ax.set_ylabel(f"{names[j]}{unit}")
        ax.set_title(names[j])
        if key is not None:
            err = measured[:, j] - np.asarray(predicted[key]).reshape(len(t), -1)[:, j]
            axes[1, j].plot(t, err, color="C3", lw=0.9)
            axes[1, j].set_ylabel(f"error{unit}")
        axes[1, j].set_xlabel("time [s]")
    axes[0, 0].legend(loc="best")
    if title:
        fig.suptitle(title)
    return fig
