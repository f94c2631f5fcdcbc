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
    # the curves are the data they claim to be (exact: the plot keeps the arrays it was given)
    bode = _lines(figs[0].axes[0])
    np.testing.assert_allclose(bode["true"], np.abs(G_SISO.frequency_response(f)[:, 0, 0]), rtol=1e-12)
    np.testing.assert_allclose(bode["deduced (full order)"], np.abs(res.deduced_response(f)[:, 0, 0]), rtol=1e-12)
    np.testing.assert_allclose(bode["reduced"], np.abs(res.plant.frequency_response(f)[:, 0, 0]), rtol=1e-12)
    assert np.array_equal(figs[0].axes[0].get_lines()[0].get_xdata(), f)
    cl = _lines(figs[2].axes[0])
    np.testing.assert_allclose(cl["identified"], np.abs(res.closed_loop.frequency_response(f)[:, 0, 0]), rtol=1e-12)
    np.testing.assert_allclose(cl["FFT ratio of the data"], np.abs(etfe[:, 0]), rtol=1e-12)
    rec = _lines(figs[3].axes[0])
    np.testing.assert_array_equal(rec["measured"], exp.y[:, 0])
    np.testing.assert_array_equal(rec["identified plant, re-closed loop"], y[:, 0])
    from stageid.closedloop.cancellation import z_to_s

    sp = z_to_s(res.entries[0].poles, DT)
    sp = sp[np.abs(sp) < 2.5e4]  # the plot's default limit
    drawn = _lines(figs[1].axes[0], x=True)["poles"]
    assert drawn.size == sp.size > 0
    np.testing.assert_allclose(np.sort_complex(drawn), np.sort_complex(sp), rtol=1e-12)


def _lines(ax, x: bool = False) -> dict:
    """Label -> y data (or x + i y with ``x``) of every labelled line on ``ax``."""
    out = {}
    for line in ax.get_lines():
        yd = np.asarray(line.get_ydata(), float)
        out[line.get_label()] = np.asarray(line.get_xdata(), float) + 1j * yd if x else yd
    return out
