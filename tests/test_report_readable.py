"""Report figures a reader can read: units on every axis, log scales that stop at a sensible floor,
captions that promise only what is drawn, long fast records drawn in a window, modes in a table."""

from __future__ import annotations

import numpy as np
import pytest

from stageid.frf import FrequencyResponse
from stageid.models import StateSpaceModel
from stageid.plots import bode_figure
from stageid.plots.hysteresis import creep_figure, stage_dynamics_figure, tracking_figure
from stageid.report.frd_report import frf_caption
from stageid.report.modes import model_modes

F = np.geomspace(1.0, 100.0, 200)


def _resonance(f_n=30.0, zeta=0.05):
    w = 2 * np.pi * f_n
    return StateSpaceModel([[0.0, 1.0], [-w * w, -2 * zeta * w]], [[0.0], [w * w]], [[1.0, 0.0]], [[0.0]])


def _magnitude_axes(fig):
    return [ax for ax in fig.axes if ax.get_yscale() == "log"]


def _line_peak(ax):
    ys = [np.asarray(ln.get_ydata(), float) for ln in ax.get_lines()]
    ys = np.concatenate([y[np.isfinite(y) & (y > 0)] for y in ys])
    return ys.max()


def test_a_band_below_zero_does_not_stretch_the_log_axis_to_the_rounding_error():
    # a coupling of 1e-4 whose +-2 std band crosses zero: the old axis ran down to 1e-314
    H = np.ones((F.size, 1, 2), complex) / (1 + 1j * F[:, None, None] / 20)
    H[:, 0, 1] *= 1e-4
    std = np.abs(H) * np.array([0.01, 3.0])
    lo, hi = np.abs(H) - 2 * std, np.abs(H) + 2 * std
    fig = bode_figure(F, {"model": H}, ["Z", "Rx"], ["z"], bands={"model": (lo, hi)}, input_units=("um", "urad"))
    mags = _magnitude_axes(fig)
    assert len(mags) == 2
    for ax in mags:
        assert ax.get_ylim()[0] >= 1e-8 * _line_peak(ax)  # at most a few decades below the entry's own peak
    assert [ax.get_ylabel() for ax in mags] == ["|G| [output/um]", "|G| [output/urad]"]  # z's unit is not known
    assert "model band" in [t.get_text() for t in mags[0].get_legend().get_texts()]


def test_a_numerically_zero_entry_says_so_instead_of_plotting_1e_300():
    H = np.ones((F.size, 2, 1), complex)
    H[:, 1, 0] = 1e-300  # a coupling that is zero but for rounding
    fig = bode_figure(F, {"model": H}, ["u"], ["a", "b"], phase=False)
    top, bottom = _magnitude_axes(fig)
    notes = [t.get_text() for t in bottom.texts]
    assert notes == ["below 1e-06 (numerically zero)"]
    assert bottom.get_ylim()[0] > 1e-7  # the axis of the largest entry's range, not of the zero
    assert not top.texts


def test_every_bode_axis_has_a_y_label_with_a_unit():
    fig = bode_figure(
        F, {"m": np.ones((F.size, 2, 2), complex)}, ["Fx", "Tphi"], ["x", "phi"], output_units=("m", "rad")
    )
    for ax in fig.axes:
        label = ax.get_ylabel()
        assert label.endswith("]") and "[" in label, label
    assert fig.axes[0].get_ylabel() == "|G| [m/input]" and fig.axes[2].get_ylabel() == "phase [deg]"


def _frd(std: bool, coherence: bool):
    G = _resonance().frequency_response(F)
    return FrequencyResponse(
        F, G, 0.01 * np.abs(G) if std else None, np.full((F.size, 1), 0.99) if coherence else None, ("V",), ("y",)
    )


@pytest.mark.parametrize("std, coherence", [(True, True), (False, False), (True, False)])
def test_the_frf_caption_promises_exactly_what_the_figure_draws(std, coherence):
    frd = _frd(std, coherence)
    fig = frd.plot(model=_resonance(), fit_band=(2.0, 50.0), input_units=("V",), output_units=("um",))
    legends = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    caption = frf_caption(frd, fit_band=(2.0, 50.0))
    assert ("data +-2 std" in legends) == std and ("shaded: +-2 std" in caption) == std
    assert ("no band: the data give no std" in caption) == (not std)
    assert ("y coherence" in legends) == coherence and ("bottom: multiple coherence" in caption) == coherence
    assert ("no coherence panel" in caption) == (not coherence)
    assert "not fitted" in legends and "grey: outside the fitted band 2-50 Hz" in caption
    assert fig.axes[0].get_ylabel() == "|G| [um/V]"
    # the data outside the fitted band are drawn, not cut away
    assert fig.axes[0].get_lines()[0].get_xdata().max() == F[-1]


def test_frf_band_wider_than_the_magnitude_stays_within_the_axis_floor():
    frd = _frd(True, True)
    wide = FrequencyResponse(F, frd.response, 5 * np.abs(frd.response), frd.coherence, ("V",), ("y",))
    ax = wide.plot().axes[0]
    assert ax.get_ylim()[0] >= 1e-8 * _line_peak(ax)


def test_modes_of_a_continuous_and_a_sampled_resonance_agree():
    g = _resonance(f_n=120.0, zeta=0.02)
    (cont,) = model_modes(g)
    (disc,) = model_modes(g.c2d(1e-4))
    assert cont.kind == disc.kind == "complex pair"
    assert cont.frequency_hz == pytest.approx(120.0, rel=1e-12)  # analytic: |s| / 2 pi
    assert cont.damping == pytest.approx(0.02, rel=1e-12)
    # zoh maps s to z = exp(s Ts) exactly: ln(z) / Ts gives the mode back to rounding
    assert disc.frequency_hz == pytest.approx(120.0, rel=1e-9) and disc.damping == pytest.approx(0.02, rel=1e-7)


def test_a_long_scan_is_drawn_as_a_window_and_an_envelope():
    dt, period = 1e-4, 0.01
    t = np.arange(0, 5.0, dt)
    ref = np.abs(((t / period) % 1.0) * 2 - 1)  # a 100 Hz triangle for 5 s: 500 periods
    err = 1e-3 * np.sin(2 * np.pi * 37 * t)
    err[100] = 0.25  # one spike the envelope must keep
    fig = tracking_figure(t, ref, ref + err, title="scan", period=period)
    zoom, whole, loop = fig.axes
    lo, hi = zoom.get_lines()[0].get_xdata()[[0, -1]]
    assert hi - lo <= 3 * period + dt  # a few periods, not a solid block
    (band,) = whole.collections[:1]
    assert band.get_paths()[0].vertices[:, 1].max() == pytest.approx(0.25)  # the spike survives
    assert zoom.get_ylabel() == "displacement [um]" and whole.get_ylabel() == "error [um]"
    assert len(tracking_figure(t[:500], ref[:500], ref[:500], period=period).axes) == 2  # short: drawn whole


def test_stage_dynamics_and_creep_figures_have_units_and_mark_the_modes():
    from stageid.hysteresis import PIModel
    from stageid.hysteresis.models.creep import CreepTerm
    from stageid.hysteresis.stage import StageModel

    dynamics = _resonance(f_n=700.0, zeta=0.02).c2d(1e-4)
    stage = StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), dynamics, disturbance_modes=((700.0, 0.02),))
    fig = stage_dynamics_figure(stage, "um")
    assert fig.axes[0].get_ylabel() == "|G| [um/um]"
    assert "mode 700 Hz (damping 0.02)" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    creep = creep_figure(CreepTerm([0.1, 2.0], [0.01, 0.02], 1e-3), "V", "um")
    ax = creep.axes[0]
    assert ax.get_ylabel() == "creep after a unit input step [um/V]" and ax.get_xlabel() == "time after the step [s]"
    total = ax.get_lines()[0].get_ydata()
    assert total[-1] == pytest.approx(0.03, rel=1e-2)  # sum of the weights after 5 of the longest time constant


def test_a_long_validation_record_is_shown_in_a_window_of_a_few_periods(monkeypatch):
    from stageid.data import Experiment
    from stageid.report import html as report_html
    from stageid.report.model_report import lti_model_report

    drawn = []
    real = report_html.Report.figure
    monkeypatch.setattr(
        report_html.Report, "figure", lambda self, fig, caption, dpi=110: (drawn.append(fig), real(self, fig, caption))
    )
    g = _resonance(f_n=400.0, zeta=0.1).c2d(1e-4)
    t = np.arange(0, 5.0, 1e-4)
    u = np.sign(np.sin(2 * np.pi * 100 * t))[:, None]  # a 100 Hz square drive for 5 s
    exp = Experiment(u, g.simulate(u), 1e-4, g.inputs, g.outputs, output_units=("um",), name="scan")
    report, _ = lti_model_report(g, [exp])
    overlay = drawn[-1]
    top, bottom = overlay.axes[0], overlay.axes[1]
    x = top.get_lines()[0].get_xdata()
    assert x[-1] - x[0] == pytest.approx(0.03, abs=2e-4)  # three 100 Hz periods, not 500
    assert bottom.get_xlim()[1] >= 4.9  # the error over the whole record
    assert top.get_ylabel() == f"{g.outputs[0]} [um]" and bottom.get_ylabel() == "error [um]"
    assert "the last three periods (4.97-5 s) above" in report.to_html()
