"""Figures of the Hankel-MAP identification (Agg, no display)."""

import numpy as np

from stageid.data import Experiment
from stageid.models import StateSpaceModel
from stageid.plots.subspace import bode_with_bands, error_curve, selection_plot
from stageid.subspace import HankelMAP
from stageid.subspace.selection import SelectionTable


def test_bode_with_bands_and_selection_figures(tmp_path):
    g = StateSpaceModel([[0.9, 0.1], [-0.1, 0.8]], [[1.0], [0.5]], [[0.1, 0.0], [0.0, 0.2]], [[0.0], [0.0]], dt=0.01)
    u = np.random.default_rng(0).standard_normal((3000, 1))
    y = g.simulate(u) + 0.001 * np.random.default_rng(1).standard_normal((3000, 2))
    res = HankelMAP(horizon=8, order=2).fit(Experiment(u, y, 0.01))
    fig = bode_with_bands(res, np.linspace(0.1, 50, 80), g, title="test")
    assert len(fig.axes) == 2
    fig.savefig(tmp_path / "bode.png")
    table = SelectionTable("horizon", (4, 8, 12), (0.3, 0.1, float("inf")), 8)
    fig2 = selection_plot(table)
    fig2.savefig(tmp_path / "sel.png")
    fig3 = error_curve([1, 2, 3], {"a": [1.0, 0.5, 0.2], "b": [2.0, 1.0, 0.1]}, "order", chosen=2)
    assert len(fig3.axes[0].lines) >= 2
    assert (tmp_path / "bode.png").stat().st_size > 1000
