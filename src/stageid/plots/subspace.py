"""Figures for the Hankel-MAP identification: Bode plots with uncertainty bands, selection curves.

Every function returns a :class:`matplotlib.figure.Figure` built on the Agg canvas (no
pyplot state, no ``show``); save it with ``fig.savefig(path)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .scale import magnitude_label, peak, set_log_magnitude
from .style import figure, loglog, positive

__all__ = ["bode_with_bands", "selection_plot", "error_curve"]


def _figure(width: float, height: float):
    return figure((width, height))


def bode_with_bands(
    result: Any,
    freqs_hz: Sequence[float] | np.ndarray,
    true_model: Any = None,
    n_std: float = 2.0,
    title: str = "",
    input_units: Sequence[str] = (),
    output_units: Sequence[str] = (),
) -> Any:
    """Magnitude of every entry: identified model, the Hankel-Toeplitz response with +-``n_std``
    posterior bands, and optionally the true model.

    Parameters
    ----------
    result : HankelMAPResult
    freqs_hz : array_like of shape (n_freqs,)
    true_model : StateSpaceModel, optional
    n_std : float
        Width of the band in standard deviations.
    input_units, output_units : sequence of str, optional
        The channels' units, for the magnitude labels (``output/input`` when not given).

    Each magnitude axis shows its lines' peak down to a millionth of it
    (:func:`~stageid.plots.scale.set_log_magnitude`): a band whose lower edge
    ``|G| - n_std std`` is below zero runs to the bottom of the axis.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> from stageid.models import StateSpaceModel
    >>> from stageid.subspace import HankelMAP
    >>> g = StateSpaceModel([[0.9]], [[1.0]], [[0.1]], [[0.0]], dt=0.01)
    >>> u = np.random.default_rng(0).standard_normal((2000, 1))
    >>> res = HankelMAP(horizon=5, order=1).fit(Experiment(u, g.simulate(u), 0.01))
    >>> fig = bode_with_bands(res, np.linspace(0.1, 50, 50), g)
    >>> len(fig.axes)
    1
    """
    f = np.asarray(freqs_hz, dtype=float)
    model = result.model
    G = model.frequency_response(f)
    Gh, std = result.response_bands(f)
    G_true = None if true_model is None else true_model.frequency_response(f)
    q, m = G.shape[1:]
    fig = _figure(3.2 * m, 2.4 * q)
    axes = fig.subplots(q, m, squeeze=False, sharex=True)
    for i in range(q):
        for j in range(m):
            ax = axes[i, j]
            mag = np.abs(Gh[:, i, j])
            upper = positive(mag + n_std * std[:, i, j])
            lo = np.fmin(np.clip(mag - n_std * std[:, i, j], 1e-300, None), upper)
            ax.fill_between(
                positive(f), lo, upper, color="C0", alpha=0.25, lw=0, label=f"eq. 9 response +-{n_std:g} std"
            )
            loglog(ax, f, np.abs(G[:, i, j]), "C0", lw=1.2, label="identified model")
            if G_true is not None:
                loglog(ax, f, np.abs(G_true[:, i, j]), "k--", lw=1, label="true")
            ax.set_title(f"{model.inputs[j]} -> {model.outputs[i]}", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.set_ylabel(magnitude_label(_at(output_units, i), _at(input_units, j)), fontsize=8)
            if i == q - 1:
                ax.set_xlabel("frequency [Hz]", fontsize=8)
    lines = [np.abs(G)] + ([] if G_true is None else [np.abs(G_true)])
    top = peak(lines)
    for i in range(q):
        for j in range(m):
            set_log_magnitude(axes[i, j], [v[:, i, j] for v in lines], reference_peak=top or None)
    axes[0, 0].legend(fontsize=6)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return fig


def _at(units: Sequence[str], k: int) -> str:
    return units[k] if k < len(units) else ""


def selection_plot(table: Any, title: str = "") -> Any:
    """Held-out error versus horizon or order (a :class:`~stageid.subspace.selection.SelectionTable`)."""
    return error_curve(
        table.values,
        {"held-out error": table.errors},
        xlabel=table.kind,
        ylabel="held-out error [error energy / output energy]",
        chosen=table.chosen,
        title=title,
    )


def error_curve(
    x: Sequence[float],
    curves: dict[str, Sequence[float]],
    xlabel: str,
    ylabel: str = "error",
    chosen: float | None = None,
    title: str = "",
    logy: bool = True,
) -> Any:
    """One or several error curves against a hyper-parameter (Fig. 4 / Tables 4-6 style)."""
    fig = _figure(4.5, 3.0)
    ax = fig.subplots()
    for name, y in curves.items():
        y = np.asarray(y, dtype=float)
        ok = np.isfinite(y) & (y > 0) if logy else np.isfinite(y)  # a log axis shows positive errors only
        ax.plot(np.asarray(x)[ok], y[ok], "o-", ms=3, label=name)
    if chosen is not None:
        ax.axvline(chosen, color="k", ls=":", lw=1, label=f"chosen {chosen}")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig
