"""Figures of hysteresis modelling and compensation (the letter's Figs. 4-8 and 10-12); Agg-safe.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (no window,
no global state); save it with ``fig.savefig(path)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .style import subplots

__all__ = [
    "loop_figure",
    "loop_error_figure",
    "reversal_window",
    "model_errors_figure",
    "tracking_figure",
    "creep_figure",
    "stage_dynamics_figure",
]


#: Cycles of the input a long record's loops are drawn for (the last ones).
N_CYCLES = 3
#: A reversal of the input counts once it has moved back by this fraction of its range.
REVERSAL_FRACTION = 0.05


def _figure(nrows: int, ncols: int, size: tuple[float, float]):
    return subplots(nrows, ncols, figsize=size, squeeze=False)


def _flat(a: Any) -> np.ndarray:
    return np.asarray(a, dtype=float).reshape(-1)


def _curves_figure(
    x: Any, curves: Mapping[str, Any], size: tuple[float, float], lw: float, labels: tuple[str, str, str]
) -> Any:
    """One axis with every curve of ``curves`` against ``x``, labelled ``(xlabel, ylabel, title)``."""
    fig, axes = _figure(1, 1, size)
    ax = axes[0, 0]
    xs = _flat(x)
    for label, y in curves.items():
        ax.plot(xs, _flat(y), lw=lw, label=label)
    xlabel, ylabel, title = labels
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.legend()
    return fig


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
    return _curves_figure(u, curves, (5.0, 4.0), 0.8, (xlabel, ylabel, title))


def loop_error_figure(
    time: Any,
    u: Any,
    y: Any,
    y_hat: Any,
    labels: tuple[str, str],
    error_label: str,
    scale: float = 1.0,
    band: Any = None,
    band_label: str = "",
) -> Any:
    """Measured and modelled loops beside the modelling error ``(y - y_hat) * scale`` over time.

    A record of many loops drawn whole is a solid block: when its input turns more than
    ``4 * N_CYCLES`` times back and forth (:func:`reversal_window`), (a) draws the loops of the
    last ``N_CYCLES`` cycles over the whole record's in grey, (b) the error in that window and
    (c) the error over the whole record as its min-max envelope with the window marked.
    Otherwise (a) the loops and (b) the error, whole.

    Parameters
    ----------
    time, u, y, y_hat : array_like of shape (n_samples,)
    labels : (str, str)
        The loop's x and y labels (input and output with their units).
    error_label : str
        The error axis's label (its unit: ``scale`` turns the output's unit into it).
    band : array_like of shape (n_samples,), optional
        Half-width of a band around the model's output (output units): drawn as the loop's
        edges (colour C1) and, times ``scale``, shaded around zero under the error.
    band_label : str

    Returns
    -------
    matplotlib.figure.Figure
        Two panels, or three for a long record of a fast input; Agg canvas.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0, 5, 1e-3)
    >>> u = np.sin(2 * np.pi * 10 * t)
    >>> fig = loop_error_figure(t, u, u**3, 0.9 * u**3, ("V [V]", "y [um]"), "error [um]")
    >>> [ax.get_title()[:3] for ax in fig.axes]
    ['(a)', '(b)', '(c)']
    """
    t, x, y, y_hat = _flat(time), _flat(u), _flat(y), _flat(y_hat)
    window = reversal_window(t, x)
    half = None if band is None else _flat(band)
    error = (y - y_hat) * scale
    fig, axes = _figure(1, 3 if window else 2, (15.0 if window else 11.0, 4.2))
    shown = slice(None) if window is None else (t >= window[0]) & (t <= window[1])
    span = "" if window is None else f", last {N_CYCLES} cycles ({window[1] - window[0]:.3g} s)"
    a, b = axes[0, 0], axes[0, 1]
    if window is not None:
        a.plot(x, y, color="0.85", lw=0.6, label="measured, whole record")
    a.plot(x[shown], y[shown], color="0.2", lw=1.2, label="measured")
    a.plot(x[shown], y_hat[shown], "--", color="C0", lw=1.0, label="model")
    if half is not None:
        for sign in (1.0, -1.0):
            edge = (y_hat + sign * half)[shown]
            a.plot(x[shown], edge, color="C1", lw=0.6, label=None if sign < 0 else "band edges")
    a.set(xlabel=labels[0], ylabel=labels[1], title=f"(a) loops{span}")
    a.legend()
    if half is not None:
        band_shown = (half * scale)[shown]
        b.fill_between(t[shown], -band_shown, band_shown, color="C1", alpha=0.35, label=band_label)
    b.plot(t[shown], error[shown], color="C3", lw=0.9, label="measured - model")
    b.set(xlabel="time [s]", ylabel=error_label, title=f"(b) modelling error{span}")
    if half is not None:
        b.legend()
    if window is not None:
        _envelope_panel(axes[0, 2], t, error, window, error_label)
    return fig


def reversal_window(time: Any, u: Any, n_cycles: int = N_CYCLES) -> tuple[float, float] | None:
    """``(t0, t1)``: the input's last ``n_cycles`` full cycles (from its ``2 n_cycles + 1``-th last
    reversal to the end) when it has more than ``4 n_cycles`` cycles, else None.

    A reversal is where the input turns after moving at least ``REVERSAL_FRACTION`` of its
    range, so sensor noise is no cycle and an idle stretch or a slow trend (the staircase of a
    reversal-curve record) does not hide the cycles, as a dominant spectral period would.

    >>> t = np.arange(0, 2, 1e-3)
    >>> reversal_window(t, np.sin(2 * np.pi * 20 * t))  # 40 cycles of 50 ms: the last three
    (1.837, 1.999)
    >>> reversal_window(t, np.sin(2 * np.pi * 2 * t)) is None  # four cycles are drawn whole
    True
    """
    t, x = _flat(time), _flat(u)
    if x.size < 3 or not np.ptp(x) > 0:
        return None
    slope = np.sign(np.diff(x))
    moving = np.flatnonzero(slope)
    turns = moving[1:][slope[moving[1:]] != slope[moving[:-1]]]  # local extrema of the moving input
    candidates = np.r_[0, turns, x.size - 1]
    reversals = _dead_band_turns(x[candidates], REVERSAL_FRACTION * float(np.ptp(x)))
    if len(reversals) <= 4 * 2 * n_cycles:
        return None
    return float(t[candidates[reversals[-2 * n_cycles - 1]]]), float(t[-1])


def _dead_band_turns(v: np.ndarray, band: float) -> list[int]:
    """Indices of ``v`` where it turns after a move of at least ``band`` (a peak-valley filter)."""
    turns: list[int] = []
    hi = lo = 0
    rising = 0  # 0: no move beyond the band yet
    for j in range(1, v.size):
        if rising >= 0 and v[j] >= v[hi]:
            hi = j
        if rising <= 0 and v[j] <= v[lo]:
            lo = j
        if rising >= 0 and v[hi] - v[j] >= band:
            if rising > 0:
                turns.append(hi)
            rising, lo = -1, j
        elif rising <= 0 and v[j] - v[lo] >= band:
            if rising < 0:
                turns.append(lo)
            rising, hi = 1, j
    return turns


def _envelope_panel(ax: Any, t: np.ndarray, error: np.ndarray, window: tuple[float, float], label: str) -> None:
    """(c): the error over the whole record as its min-max envelope, the zoom window shaded."""
    from .scale import envelope

    te, lo, hi = envelope(t, error)
    ax.fill_between(te, lo, hi, color="C3", lw=0.6, label="error (min-max per bin)")
    ax.axvspan(*window, color="0.85", zorder=0, label="window of (a), (b)")
    ax.set(xlabel="time [s]", ylabel=label, title="(c) modelling error over the whole record")
    ax.legend()


def model_errors_figure(
    time: Any, errors: Mapping[str, Any], ylabel: str = "modelling error [um]", title: str = ""
) -> Any:
    """Modelling-error traces of several models over time (Fig. 8)."""
    return _curves_figure(time, errors, (7.0, 3.2), 0.7, ("time [s]", ylabel, title))


def tracking_figure(
    time: Any, reference: Any, output: Any, title: str = "", unit: str = "um", period: float | None = None
) -> Any:
    """Desired and real outputs with the error (a) and the hysteresis curve (b), as Figs. 10-12.

    A record of many periods of a fast scan drawn whole is a solid block: with ``period`` (of
    the reference, seconds) and a record longer than twelve periods, (a) shows the last three
    periods, (b) the error over the whole record as its min-max envelope, and (c) the curve.

    Parameters
    ----------
    time, reference, output : array_like of shape (n_samples,)
    title : str
    unit : str
    period : float, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from .scale import envelope, zoom_window

    t, r, y = _flat(time), _flat(reference), _flat(output)
    window = None if period is None else zoom_window(t, period)
    fig, axes = _figure(1, 3 if window else 2, (14.0 if window else 10.0, 3.8))
    ax = axes[0, 0]
    shown = slice(None) if window is None else (t >= window[0]) & (t <= window[1])
    ax.plot(t[shown], r[shown], lw=0.9, label="desired")
    ax.plot(t[shown], y[shown], lw=0.9, label="real")
    ax.plot(t[shown], (y - r)[shown], lw=0.8, label="error")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"displacement [{unit}]")
    zoom = "" if window is None else f" last {window[1] - window[0]:.3g} s"
    ax.set_title(("(a) " + title if title else "(a)") + zoom)
    ax.legend()
    if window is not None:
        ax = axes[0, 1]
        te, lo, hi = envelope(t, y - r)
        ax.fill_between(te, lo, hi, color="C2", lw=0.6, label="error (min-max per bin)")
        ax.axvspan(*window, color="0.85", zorder=0, label="window of (a)")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"error [{unit}]")
        ax.set_title("(b) error over the whole record")
        ax.legend()
    ax = axes[0, -1]
    ax.plot(r, y, lw=0.9)
    lo, hi = float(min(r.min(), y.min())), float(max(r.max(), y.max()))
    ax.plot([lo, hi], [lo, hi], "k--", lw=0.6)
    ax.set_xlabel(f"desired [{unit}]")
    ax.set_ylabel(f"real [{unit}]")
    ax.set_title(f"({'c' if window else 'b'}) hysteresis curve")
    return fig


def creep_figure(creep: Any, input_unit: str = "", output_unit: str = "") -> Any:
    """The creep term's response to a unit step of the input: ``sum_j c_j (1 - exp(-t / tau_j))``.

    Drawn on a log time axis from one sample to five times the longest time constant, each lag's
    share dashed, the time constants marked.  The y axis is in output units per input unit.

    Examples
    --------
    >>> from stageid.hysteresis.creep import CreepTerm
    >>> fig = creep_figure(CreepTerm([0.1, 1.0], [0.02, 0.01], 1e-3), "V", "um")
    >>> fig.axes[0].get_ylabel()
    'creep after a unit input step [um/V]'
    """
    from .scale import magnitude_unit

    taus, weights = np.asarray(creep.time_constants, float), np.asarray(creep.weights, float)
    t = np.geomspace(creep.sample_time, 5.0 * taus.max(), 400)
    shares = weights[None, :] * (1.0 - np.exp(-t[:, None] / taus[None, :]))
    fig, axes = _figure(1, 1, (6.4, 3.4))
    ax = axes[0, 0]
    ax.semilogx(t, shares.sum(axis=1), color="k", lw=1.4, label=f"creep (total {weights.sum():.3g})")
    for tau, share in zip(taus, shares.T):
        ax.semilogx(t, share, "--", lw=0.9, label=f"lag tau = {tau:g} s")
    ax.set_xlabel("time after the step [s]")
    ax.set_ylabel(f"creep after a unit input step [{magnitude_unit(output_unit, input_unit)}]")
    ax.set_title("Creep: slow response to an input step")
    ax.legend(loc="best")
    return fig


def stage_dynamics_figure(model: Any, output_unit: str = "") -> Any:
    """Bode magnitude and phase of a stage model's linear dynamics (unit DC gain, from the hysteresis
    output to the stage output, so the magnitude is dimensionless), from a ten-thousandth of the
    Nyquist frequency to Nyquist, with the modes taken from the disturbance spectrum marked."""
    from .lti import bode_figure

    g = model.dynamics
    nyquist = 0.5 / g.dt
    f = np.geomspace(nyquist * 1e-4, nyquist, 600)
    unit = f"{output_unit}/{output_unit}" if output_unit else "-"
    fig = bode_figure(
        f,
        {"dynamics": g.frequency_response(f)},
        ["hysteresis output"],
        list(model.outputs),
        title=f"Linear dynamics of the stage (order {g.n_states}, DC gain 1)",
        magnitude_unit=unit,
    )
    for ax in fig.axes:
        for freq, damping in model.disturbance_modes:
            label = f"mode {freq:.4g} Hz (damping {damping:.3g})" if ax is fig.axes[0] else None
            ax.axvline(freq, color="C3", ls=":", lw=1.1, label=label)
    if model.disturbance_modes:
        fig.axes[0].legend(loc="best")
    return fig
