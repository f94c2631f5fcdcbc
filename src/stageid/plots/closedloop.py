"""Figures of a closed-loop identification (Shakir & Kim, Fig. 4, 6, 7, 8); Agg-safe.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot, so it
works headless; save it with ``fig.savefig(path)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .scale import magnitude_label, set_log_magnitude
from .style import loglog, subplots

__all__ = ["plot_plant_bode", "plot_closed_loop_bode", "plot_pole_zero", "plot_reclosed_loop"]


def _figure(nrows: int, ncols: int, size: tuple[float, float]):
    return subplots(nrows, ncols, figsize=size, squeeze=False)


def plot_plant_bode(
    result: Any,
    freqs_hz: np.ndarray | None = None,
    true_plant: Any = None,
    input_units: Sequence[str] = (),
    output_units: Sequence[str] = (),
) -> Any:
    """Magnitude of every plant entry: reduced fit, full-order deduction, truth (Fig. 7).

    Parameters
    ----------
    result : ClosedLoopResult
    freqs_hz : ndarray, optional
        Default 300 log-spaced lines from 1 Hz to 0.4 / dt.
    true_plant : model with ``frequency_response``, optional
        The true (continuous) plant, drawn thin.
    input_units, output_units : sequence of str, optional
        The channels' units, for the magnitude labels (``output/input`` when not given).

    Returns
    -------
    matplotlib.figure.Figure
    """
    f = np.geomspace(1.0, 0.4 / result.dt, 300) if freqs_hz is None else np.asarray(freqs_hz, float)
    p = result.closed_loop.n_outputs
    fig, axes = _figure(p, p, (3.2 * p, 2.6 * p))
    full = result.deduced_response(f)
    red = result.model.frequency_response(f)
    tru = None if true_plant is None else true_plant.frequency_response(f)
    for i in range(p):
        for j in range(p):
            ax = axes[i, j]
            if tru is not None:
                loglog(ax, f, np.abs(tru[:, i, j]), "k-", lw=0.8, label="true")
            loglog(ax, f, np.abs(full[:, i, j]), "--", lw=1.6, label="deduced (full order)")
            loglog(ax, f, np.abs(red[:, i, j]), "-", lw=1.6, label="reduced")
            ax.axvspan(*result.band, color="0.9", zorder=0, label="identification band" if i + j == 0 else None)
            ax.set_title(f"{result.model.inputs[j]} -> {result.model.outputs[i]}", fontsize=9)
            ax.set_ylabel(magnitude_label(_at(output_units, i), _at(input_units, j)), fontsize=8)
            lines = [np.abs(full[:, i, j]), np.abs(red[:, i, j])] + ([] if tru is None else [np.abs(tru[:, i, j])])
            set_log_magnitude(ax, lines)
            if i == p - 1:
                ax.set_xlabel("frequency [Hz]")
    axes[0, 0].legend(fontsize=7)
    return fig


def _at(units: Sequence[str], k: int) -> str:
    return units[k] if k < len(units) else ""


def plot_closed_loop_bode(
    freqs_hz: np.ndarray,
    identified: np.ndarray,
    empirical: tuple[np.ndarray, np.ndarray] | None = None,
    true: np.ndarray | None = None,
    title: str = "",
    unit: str = "output/input",
) -> Any:
    """One closed-loop entry: identified ``T`` vs the FFT ratio of the data and the truth (Fig. 4b);
    ``unit`` is the magnitude's (e.g. ``m/m`` from a reference to its output)."""
    fig, axes = _figure(1, 1, (5.0, 3.4))
    ax = axes[0, 0]
    if empirical is not None:
        loglog(ax, empirical[0], np.abs(empirical[1]), "-", lw=0.5, color="0.6", label="FFT ratio of the data")
    if true is not None:
        loglog(ax, freqs_hz, np.abs(true), "k--", lw=1.0, label="true")
    loglog(ax, freqs_hz, np.abs(identified), "-", lw=1.8, label="identified")
    set_log_magnitude(ax, [np.abs(identified)] + ([] if true is None else [np.abs(true)]))
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"|T| [{unit}]")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)
    return fig


def plot_pole_zero(result: Any, entry: tuple[int, int] = (0, 0), limit: float = 2.5e4) -> Any:
    """Pole-zero maps of one entry: full-order deduction (Fig. 6a) and reduced fit (Fig. 6b), s-plane."""
    fig, axes = _figure(1, 2, (9.0, 3.8))
    ent = next(e for e in result.entries if (e.output, e.input) == tuple(entry))
    # s = ln(z) / dt; z = 0 goes to -inf, which the |s| < limit filter below drops
    with np.errstate(divide="ignore"):
        sp, sz = (np.log(np.asarray(z, complex)) / result.dt for z in (ent.poles, ent.zeros))
    keep_p, keep_z = np.abs(sp) < limit, np.abs(sz) < limit
    axes[0, 0].plot(sp.real[keep_p], sp.imag[keep_p], "x", label="poles")
    axes[0, 0].plot(sz.real[keep_z], sz.imag[keep_z], "o", mfc="none", label="zeros")
    axes[0, 0].set_title(f"full order ({ent.poles.size} poles), entry {entry}", fontsize=9)
    red = result.reduced.get(tuple(entry))
    if red is not None:
        axes[0, 1].plot(red.poles.real, red.poles.imag, "x")
        if red.zeros.size:
            axes[0, 1].plot(red.zeros.real, red.zeros.imag, "o", mfc="none")
        axes[0, 1].set_title(f"reduced [{red.num.size - 1}, {red.den.size - 1}]", fontsize=9)
    for ax in axes[0]:
        ax.axvline(0, color="0.7", lw=0.8)
        ax.set_xlabel("Re s [rad/s]")
        ax.set_ylabel("Im s [rad/s]")
    axes[0, 0].legend(fontsize=7)
    return fig


def plot_reclosed_loop(
    time: np.ndarray, measured: np.ndarray, simulated: np.ndarray, names: Sequence[str], units: Sequence[str] = ()
) -> Any:
    """Measured outputs beside the identified plant re-closed with the known controller (Fig. 8)."""
    y = np.atleast_2d(np.asarray(measured, float).T).T
    ys = np.atleast_2d(np.asarray(simulated, float).T).T
    fig, axes = _figure(y.shape[1], 1, (7.0, 2.2 * y.shape[1]))
    for k in range(y.shape[1]):
        ax = axes[k, 0]
        ax.plot(time, y[:, k], "-", lw=1.2, label="measured")
        ax.plot(time, ys[:, k], "--", lw=1.0, label="identified plant, re-closed loop")
        ax.set_ylabel(f"{names[k]} [{_at(units, k) or 'output unit'}]")
    axes[-1, 0].set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=7)
    return fig
