"""Figures of a closed-loop identification (Agg, no display)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from stageid.closedloop import ClosedLoopIdentification, empirical_transfer, reclose_loop  # noqa: E402
from stageid.plots.closedloop import plot_closed_loop_bode, plot_plant_bode, plot_pole_zero, plot_reclosed_loop  # noqa: E402
from test_closedloop_estimator import G_SISO, _siso_controller, _siso_experiment  # noqa: E402

DT = 2e-4


def test_figures_are_built_and_saved(tmp_path: Path) -> None:
    exp = _siso_experiment(0, duration=0.5)
    res = ClosedLoopIdentification(_siso_controller(), order_range=range(3, 7)).fit(exp)
    f = np.geomspace(1, 2000, 50)
    figs = [plot_plant_bode(res, f, G_SISO), plot_pole_zero(res, (0, 0))]
    fe, etfe = empirical_transfer(exp.u[:, 0], exp.y, DT, band=(1, 2000))
    figs.append(plot_closed_loop_bode(f, res.closed_loop.frequency_response(f)[:, 0, 0], (fe, etfe[:, 0])))
    y, _ = reclose_loop(res.plant, _siso_controller(), exp.u, DT)
    figs.append(plot_reclosed_loop(exp.time, exp.y, y, ["x"]))
    for k, fig in enumerate(figs):
        assert fig.axes  # something was drawn
        fig.savefig(tmp_path / f"f{k}.png")
        assert (tmp_path / f"f{k}.png").stat().st_size > 1000
