"""Reports read from the files they write: every number of ``metrics.json`` has its unit in the
``units`` map, the closed-loop plant Bode has the records' units, and a long hysteresis record is
drawn in a window of a few periods beside its whole-record envelope."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.collections import PolyCollection

from conftest import run_main
from stageid.data import Experiment, Table
from stageid.data.io import write_csv
from stageid.hysteresis import PIModel
from stageid.hysteresis.models.creep import CreepTerm
from stageid.models import StateSpaceModel, save_model
from stageid.plots import closedloop as closedloop_plots
from stageid.report import write_report_folder
from stageid.report.model_report import hysteresis_model_report
from stageid.report.units import numeric_paths

DT = 1e-3


def _units_of_every_number(path):
    metrics = json.loads(path.read_text())
    units = metrics.pop("units")
    paths = list(numeric_paths(metrics))
    assert paths, metrics
    missing = [p for p in paths if p not in units]
    assert missing == [], missing
    assert set(units) == set(paths)  # and no unit for a number that is not there
    return metrics, units


def _closed_loop_files(tmp_path):
    """An unstable first-order plant under a proportional controller; columns with units."""
    from stageid.models import feedback

    rng = np.random.default_rng(5)
    G = StateSpaceModel([[1.02]], [[0.05]], [[1.0]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",))
    K = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], dt=DT, inputs=("e",), outputs=("u",))  # fmt: skip
    save_model(K, tmp_path / "K.json")
    r = rng.standard_normal(4000)
    r[:100] = 0.0  # the loop starts at rest
    yu = feedback(G, K).simulate(r[:, None])
    values = np.column_stack([r, yu[:, 0] + 1e-5 * rng.standard_normal(4000), yu[:, 1]])
    write_csv(tmp_path / "exp.csv", Table(["r_y", "y", "u"], values, dt=DT, units=["um", "um", "V"]))
    return tmp_path / "exp.csv"


def test_closed_loop_report_magnitudes_in_the_records_units_and_metrics_with_units(tmp_path, monkeypatch):
    labels = {}
    for name in ("plot_plant_bode", "plot_closed_loop_bode"):
        real = getattr(closedloop_plots, name)

        def spy(*args, _real=real, _name=name, **kwargs):
            fig = _real(*args, **kwargs)
            labels[_name] = [ax.get_ylabel() for ax in fig.axes if ax.get_yscale() == "log"]
            return fig

        monkeypatch.setattr(closedloop_plots, name, spy)
    rec = _closed_loop_files(tmp_path)
    code, out, err = run_main(
        "identify", "closed-loop", rec, "--references", "r_y", "--outputs", "y", "--controller", tmp_path / "K.json",
        "--structure", "full", "--band", "1:100", "-o", tmp_path / "G.json", "--report", tmp_path / "rep",
    )  # fmt: skip
    assert code == 0, err
    assert labels["plot_plant_bode"] == ["|G| [um/V]"]  # plant: recorded plant input u [V] -> y [um]
    assert labels["plot_closed_loop_bode"] == ["|T| [um/um]"]  # closed loop: reference [um] -> y [um]
    metrics, units = _units_of_every_number(tmp_path / "rep" / "metrics.json")
    assert units["band_error_percent"] == "%" and units["unstable_poles_rad_s"] == "rad/s"
    assert units["reclosed_fit_percent/" + str(rec) + "/y"] == "%"
    assert "band_error_percent" in metrics  # the existing keys stay as they were


def test_statespace_and_validate_reports_give_every_metric_a_unit(tmp_path):
    rng = np.random.default_rng(1)
    u = rng.standard_normal(3000)
    y = np.zeros(3000)
    for k in range(2, 3000):
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + 0.2 * u[k - 1]
    write_csv(tmp_path / "r.csv", {"u": u, "y": y + 1e-3 * rng.standard_normal(3000)}, dt=DT)
    args = ["identify", "statespace", tmp_path / "r.csv", "--inputs", "u", "--outputs", "y", "--order", "2"]
    code, out, err = run_main(*args, "-o", tmp_path / "m.json", "--report", tmp_path / "ss")
    assert code == 0, err
    _, units = _units_of_every_number(tmp_path / "ss" / "metrics.json")
    assert units["fit_percent/r.csv/y"] == "%" and units["modes/frequency_hz"] == "Hz"
    code, out, err = run_main("validate", tmp_path / "m.json", tmp_path / "r.csv", "--report", tmp_path / "val")
    assert code == 0, err
    _, units = _units_of_every_number(tmp_path / "val" / "metrics.json")
    assert units["outputs/y/fit_percent"] == "%" and units["outputs/y/whiteness/statistic"].startswith("1 (chi")


def test_hysteresis_report_units_include_the_creep_gain_in_the_records_units(tmp_path):
    creep = CreepTerm(time_constants=[0.05, 0.5], weights=[0.02, 0.05], sample_time=DT)
    model = PIModel(r=[0.0, 0.5, 1.0], weights=[1.0, 0.3, 0.2], creep=creep)
    u = 1.2 * np.sin(2 * np.pi * 2.0 * np.arange(2000) * DT)
    y = model.simulate(u)
    exp = Experiment(u[:, None], y, DT, input_names=model.inputs, output_names=model.outputs, name="rec")
    exp = exp.with_(input_units=("V",), output_units=("um",))
    report, metrics = hysteresis_model_report(model, [exp])
    write_report_folder(tmp_path / "rep", report, metrics)
    _, units = _units_of_every_number(tmp_path / "rep" / "metrics.json")
    assert units["creep/total_gain"] == "um/V" and units["max_error_percent_range/rec"] == "% of the output's range"


def test_a_long_fast_hysteresis_record_is_drawn_in_a_window_beside_its_envelope(drawn):
    model = PIModel(r=[0.0, 0.4, 0.8], weights=[1.0, 0.4, 0.2])
    t = np.arange(3000) * DT
    u = 2.0 * np.abs(((20.0 * t) % 1.0) - 0.5) * (1.0 + t)  # 60 triangles of 50 ms, growing
    y = model.simulate(u)[:, 0] + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    exp = Experiment(u[:, None], y[:, None], DT, input_names=model.inputs, output_names=model.outputs, name="forc")
    hysteresis_model_report(model, [exp])
    ((fig, caption),) = drawn
    loops, window, whole = fig.axes
    # the last three cycles from the seventh-last reversal (a minimum at 2.825 s) to the end
    assert loops.get_title() == "(a) loops, last 3 cycles (0.174 s)" and "window" in caption
    in_window = [ln for ln in loops.get_lines() if ln.get_label() in ("measured", "model")]
    assert [ln.get_xdata().size for ln in in_window] == [175, 175]
    (background,) = [ln for ln in loops.get_lines() if ln.get_label() == "measured, whole record"]
    assert background.get_xdata().size == t.size
    assert window.get_lines()[0].get_xdata()[0] == pytest.approx(2.825)
    (band,) = [c for c in whole.collections if isinstance(c, PolyCollection) and c.get_label().startswith("error")]
    xs = band.get_paths()[0].vertices[:, 0]
    assert xs.min() == pytest.approx(0.0) and xs.max() > 2.9  # the envelope spans the whole record
    # a short record (a few periods) stays whole, in two panels
    drawn.clear()
    short = exp.slice(0, 300)
    hysteresis_model_report(model, [short])
    ((fig, _),) = drawn
    assert len(fig.axes) == 2 and fig.axes[0].get_lines()[0].get_xdata().size == 300


@pytest.mark.parametrize(
    "key, unit",
    [
        ("checks_passed/whiteness", "true/false"),  # closed loop without the controller
        ("hysteresis/model_error_percent_validation/pi", "%"),  # the demo's
        ("hysteresis/tracking_error_percent_fsr/modified-PI inverse", "% of the full-scale range"),
        ("maglev/rhp_poles_true_rad_s", "rad/s"),
        ("p558/z_channel_selected_order", "states"),
        ("seconds/total", "s"),
        ("loop_band/error_inside_percent/rec", "% of samples"),
        ("dynamics/modes/damping", "1 (damping ratio)"),
    ],
)
def test_metric_names_read_as_units(key, unit):
    from stageid.report.units import metric_unit

    assert metric_unit(key) == unit


def test_a_name_without_a_unit_is_left_out_not_guessed():
    from stageid.report.units import metric_units

    assert metric_units({"fit_percent/r/y": 90.0, "gain": 2.0, "method": "oe", "empty": []}) == {"fit_percent/r/y": "%"}


def test_frd_fit_report_gives_every_metric_a_unit(tmp_path):
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=0.01)
    save_model(g.with_names(inputs=("u",), outputs=("y",)), tmp_path / "m.json")
    code, out, err = run_main(
        "freqresp", tmp_path / "m.json", "--fmin", "0.1", "--fmax", "40", "--n", "200", "-o", tmp_path / "fr.csv"
    )
    assert code == 0, err
    code, out, err = run_main(
        "identify", "frd", tmp_path / "fr.csv", "--order", "2", "--dt", "0.01", "-o", tmp_path / "fit.json",
        "--report", tmp_path / "rep",
    )  # fmt: skip
    assert code == 0, err
    _, units = _units_of_every_number(tmp_path / "rep" / "metrics.json")
    assert units["delay"] == "samples" and units["band_hz"] == "Hz" and units["column_error_percent/u"] == "%"


def test_an_idle_start_and_a_staircase_do_not_hide_the_cycles():
    """A reversal-curve record: 1 s idle at the lowest drive, then 25 triangles of 20 ms whose
    peaks rise (the shape of the dSPACE records, where the strongest spectral line is the slow
    staircase, not the cycles)."""
    from stageid.plots.hysteresis import loop_error_figure, reversal_window

    dt = 1e-4
    t = np.arange(15000) * dt
    phase = np.clip(t - 1.0, 0.0, None)
    peak = -1.0 + 2.0 * np.minimum(phase / 0.5, 1.0)
    u = np.where(t < 1.0, -1.0, -1.0 + (peak + 1.0) * (1.0 - np.abs((phase * 100.0) % 2.0 - 1.0)))
    window = reversal_window(t, u)
    assert window is not None and window[1] == t[-1]
    assert window[1] - window[0] == pytest.approx(0.07, abs=2 * dt)  # three cycles to the last turn, its tail
    fig = loop_error_figure(t, u, u**3, 0.98 * u**3, ("V [V]", "y [um]"), "error [um]")
    assert len(fig.axes) == 3
    # the same cycles without the idle stretch but only four of them: drawn whole
    assert reversal_window(t[:1400], np.sin(2 * np.pi * 3 * t[:1400] / 0.14)) is None


def test_validate_report_draws_a_long_hysteresis_record_in_a_window(tmp_path, drawn):
    model = PIModel(r=[0.0, 0.4, 0.8], weights=[1.0, 0.4, 0.2])
    save_model(model, tmp_path / "pi.json")
    t = np.arange(3000) * DT
    u = 2.0 * np.abs(((20.0 * t) % 1.0) - 0.5) * (1.0 + t)
    y = model.simulate(u)[:, 0] + 0.01 * np.random.default_rng(1).standard_normal(t.size)
    write_csv(tmp_path / "r.csv", Table([*model.inputs, *model.outputs], np.column_stack([u, y]), dt=DT))
    code, out, err = run_main("validate", tmp_path / "pi.json", tmp_path / "r.csv", "--report", tmp_path / "rep")
    assert code == 0, err
    fig, caption = drawn[-1]
    assert [ax.get_title()[:3] for ax in fig.axes] == ["(a)", "(b)", "(c)"] and "and the error" in caption
    assert fig.axes[1].get_ylabel() == "error [% of range]"
