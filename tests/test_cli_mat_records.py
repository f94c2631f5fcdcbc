"""MATLAB struct files as a user passes them to the command line, and the --start/--stop window.

Synthetic files are written here (dSPACE-like struct arrays, Simulink "structure with time",
v7.3 through h5py), so these run everywhere; the shared records are read in place and skip
when the folder is absent.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io

from conftest import run_main
from stageid import DataError
from stageid.data import Table, read_table
from stageid.data import datasets as ds
from stageid.validation.edges import EDGE_FLOOR_PERCENT, edge_errors

DT = 1e-3


def _dspace(path, t, y, u, name="run_7"):
    """A ControlDesk-style export: one struct, X.Data the time, Y(1..3).Data the signals."""
    Y = np.zeros((1, 3), dtype=[("Name", object), ("Data", object), ("XIndex", object)])
    for k, sig in enumerate((y, np.zeros_like(y), u)):
        Y[0, k] = (f'"Model Root"/"s{k}"', np.asarray(sig, float)[None, :], 1.0)
    X = np.zeros((1, 1), dtype=[("Name", object), ("Data", object)])
    X[0, 0] = ("", np.asarray(t, float)[None, :])
    scipy.io.savemat(path, {name: {"X": X, "Y": Y, "Capture": {"SamplingPeriod": DT, "Task": "1"}}})


def _gain_model(path, dt, inputs, gain=2.0):
    model = {
        "format": "stageid.lti/1",
        "kind": "statespace",
        "dt": dt,
        "A": [[0.0]],
        "B": [[0.0] * len(inputs)],
        "C": [[0.0]],
        "D": [[gain] + [0.0] * (len(inputs) - 1)],
        "inputs": list(inputs),
        "outputs": ["z"],
    }
    path.write_text(json.dumps(model))
    return path


def _one_line_error(code, out, err, *words):
    assert code == 2 and out == ""
    line = err.strip()
    assert "\n" not in line, line
    for w in words:
        assert w in line, line
    return line


# ------------------------------------------------------------------ struct files, synthetic
def test_dspace_struct_simulated_through_the_cli_with_a_window(tmp_path):
    n = 200
    t = 0.5 + DT * np.arange(n)  # t0 = 0.5 s: the window is on the record's own axis
    u = np.sin(7.0 * t)
    _dspace(tmp_path / "rec.mat", t, 3.0 * u, u)
    model = _gain_model(tmp_path / "g.json", DT, ["Y(3).Data"])
    code, out, err = run_main("simulate", model, tmp_path / "rec.mat", "-o", tmp_path / "z.csv")
    assert code == 0, err
    z = read_table(tmp_path / "z.csv")
    assert (z.n_samples, z.t0) == (n, pytest.approx(0.5))
    assert np.allclose(z.column("z"), 2.0 * u)
    code, out, err = run_main(
        "simulate", model, tmp_path / "rec.mat", "--start", "0.55", "--stop", "0.6", "-o", tmp_path / "w.csv"
    )
    assert code == 0, err
    w = read_table(tmp_path / "w.csv")
    # samples 50..100 inclusive: both bounds fall on a sample
    assert (w.n_samples, w.t0) == (51, pytest.approx(0.55))
    assert np.allclose(w.column("z"), 2.0 * u[50:101])


def test_simulink_structure_with_time_and_v73_struct_array(tmp_path):
    import h5py

    n = 64
    t = 0.01 * np.arange(n)
    values = np.column_stack([np.cos(t), np.sin(t)])
    scipy.io.savemat(tmp_path / "sim.mat", {"logs": {"time": t[:, None], "signals": {"values": values}}, "k": 2.0})
    table = read_table(tmp_path / "sim.mat")  # two variables: the struct keeps its name
    assert table.names == ("logs.signals.values_1", "logs.signals.values_2")
    assert table.dt == pytest.approx(0.01) and np.array_equal(table.column("logs.signals.values_2"), values[:, 1])

    path = tmp_path / "v73.mat"
    with h5py.File(path, "w", userblock_size=512) as fh:
        store = fh.create_group("#refs#")
        rec = fh.create_group("rec")
        rec.attrs["MATLAB_class"] = np.bytes_("struct")
        x = rec.create_group("X")
        x.attrs["MATLAB_class"] = np.bytes_("struct")
        x.create_dataset("Data", data=t[None, :].T)  # HDF5 holds MATLAB arrays transposed
        y = rec.create_group("Y")  # a 1x2 struct array: one reference per element
        y.attrs["MATLAB_class"] = np.bytes_("struct")
        refs = [store.create_dataset(f"d{k}", data=values[:, k][None, :].T).ref for k in range(2)]
        y.create_dataset("Data", data=np.array(refs, dtype=h5py.ref_dtype).reshape(2, 1))
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, HDF5 schema 1.00 .".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    table = read_table(path)
    assert table.names == ("Y(1).Data", "Y(2).Data") and table.dt == pytest.approx(0.01)
    assert np.array_equal(table.column("Y(2).Data"), values[:, 1])


def test_bad_struct_files_one_line_naming_file_and_columns(tmp_path):
    model = _gain_model(tmp_path / "g.json", DT, ["Y(3).Data"])
    scipy.io.savemat(tmp_path / "params.mat", {"cfg": {"gain": 2.0, "label": "run"}})
    line = _one_line_error(
        *run_main("simulate", model, tmp_path / "params.mat", "-o", tmp_path / "o.csv"), "'params.mat'", "no numeric"
    )
    assert "gain (scalar)" in line and "label (text)" in line
    scipy.io.savemat(tmp_path / "ragged.mat", {"s": {"time": DT * np.arange(10), "a": np.ones(10), "b": np.ones(9)}})
    line = _one_line_error(
        *run_main("simulate", model, tmp_path / "ragged.mat", "-o", tmp_path / "o.csv"), "'ragged.mat'", "unequal"
    )
    assert "10 samples: time, a" in line and "9 samples: b" in line
    t = DT * np.arange(100)
    _dspace(tmp_path / "rec.mat", t, t, t)
    code, out, err = run_main(
        "identify",
        "hysteresis",
        tmp_path / "rec.mat",
        "--input",
        "Y(4).Data",
        "--output",
        "Y(1).Data",
        "-o",
        tmp_path / "h.json",
    )
    line = _one_line_error(code, out, err, "file 'rec.mat': unknown column 'Y(4).Data'")
    assert "expected one of Y(1).Data, Y(2).Data, Y(3).Data" in line
    scipy.io.savemat(tmp_path / "two.mat", {"a": {"time": t, "x": t}, "b": {"time": 2 * t, "y": t}})
    _one_line_error(
        *run_main("simulate", model, tmp_path / "two.mat", "-o", tmp_path / "o.csv"),
        "several different time vectors (a.time, b.time)",
    )
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "h.json").exists()


def test_window_errors_are_one_line(tmp_path):
    t = DT * np.arange(100)
    _dspace(tmp_path / "rec.mat", t, t, t)
    model = _gain_model(tmp_path / "g.json", DT, ["Y(3).Data"])
    for window, words in (
        (("--start", "0.05", "--stop", "0.02"), "--start 0.05 s must be before --stop 0.02 s"),
        (("--start", "5"), "keeps 0 samples of the record (0 s to 0.099 s)"),
        (("--stop", "nan"), "expected a finite time"),
    ):
        code, out, err = run_main("simulate", model, tmp_path / "rec.mat", *window, "-o", tmp_path / "o.csv")
        assert code == 2 and words in err and err.count("\n") == 1, err
    assert not (tmp_path / "o.csv").exists()


def test_table_between_keeps_the_caller_table():
    table = Table(["u"], np.arange(10.0), dt=0.5, t0=1.0, source="r.csv")
    part = table.between(start=2.2)  # 2.2 s lies between samples: the next one is the first kept
    assert part.t0 == 2.5 and part.column("u")[0] == 3.0 and table.n_samples == 10
    assert table.between(stop=1.5).column("u").tolist() == [0.0, 1.0]
    with pytest.raises(DataError, match=r"^file 'r.csv': `start=`/`stop=` window \[5.1 s, 5.2 s\] keeps 0 samples"):
        table.between(5.1, 5.2)


# ------------------------------------------------------------------ transient hint
def test_edge_rule_fires_on_a_transient_only():
    rng = np.random.default_rng(3)
    e = 0.002 * rng.standard_normal(2000)  # middle errors ~0.8 % of a unit range at most
    assert edge_errors(e, 1.0, DT) == ()  # white errors: no edge holds 3x the middle's largest
    # a fit error of one level everywhere (the trim keeps what the middle's largest bounds)
    e = 0.005 * np.sin(0.3 * np.arange(2000))
    head = e.copy()
    head[:30] += 0.2 * np.exp(-np.arange(30) / 5.0)
    (found,) = edge_errors(head, 1.0, DT, t0=1.0)
    assert (
        found.edge == "start"
        and 10 < found.n_samples <= 30
        and found.trim_at == pytest.approx(1.0 + found.n_samples * DT)
    )
    tail = e.copy()
    tail[-1] = 0.4  # a reset drive on the last sample
    (found,) = edge_errors(tail, 1.0, DT)
    assert (found.edge, found.n_samples, found.trim_at) == ("stop", 1, pytest.approx(1998 * DT))
    small = 1e-5 * rng.standard_normal(2000)
    small[:5] = 0.5 * EDGE_FLOOR_PERCENT / 100  # 10x the rest, but below the floor worth trimming for
    assert edge_errors(small, 1.0, DT) == ()
    spread = e.copy()
    spread[1000] = 0.2  # the largest error in the middle: no edge to blame
    spread[:30] += 0.2
    assert edge_errors(spread, 1.0, DT) == ()


def test_hysteresis_summary_points_at_a_start_transient_and_start_removes_it(tmp_path):
    from stageid.hysteresis import PIModel
    from stageid.signals import decaying_triangle

    dt = 2e-3
    u = decaying_triangle(1.0, 6, dt, amplitude=360.0)
    y = PIModel(r=np.arange(6) * 60.0, weights=[0.01, 0.004, 0.003, 0.002, 0.001, 0.001]).simulate(u)[:, 0]
    y_transient = y.copy()
    y_transient[:40] += 0.3 * np.ptp(y) * np.exp(-np.arange(40) / 6.0)  # a sensor settling at the start
    t = dt * np.arange(u.size)
    _dspace(tmp_path / "clean.mat", t, y, u)
    _dspace(tmp_path / "rec.mat", t, y_transient, u)
    args = ["--input", "Y(3).Data", "--output", "Y(1).Data", "--model", "pi", "--operators", "6"]
    code, out, err = run_main("identify", "hysteresis", tmp_path / "rec.mat", *args, "-o", tmp_path / "h.json")
    assert code == 0, err
    text = out + err
    assert "a start-up transient; try --start" in text, text
    start = float(text.split("try --start ")[1].split()[0])
    assert 0 < start <= 40 * dt
    code, out, err = run_main(
        "identify", "hysteresis", tmp_path / "rec.mat", *args, "--start", str(start), "-o", tmp_path / "h2.json"
    )
    assert code == 0 and "transient" not in out + err
    max_error = float((out + err).split("max error ")[1].split()[0])
    assert max_error < 1.0  # the exact model class: what is left after the window is fit error only
    code, out, err = run_main("identify", "hysteresis", tmp_path / "clean.mat", *args, "-o", tmp_path / "h3.json")
    assert code == 0 and "transient" not in out + err
    # the Preisach identifier's summary too
    code, out, err = run_main(
        "identify", "hysteresis", tmp_path / "rec.mat", *args[:4], "--model", "preisach", "-o", tmp_path / "p.json"
    )
    assert code == 0 and "Preisach model" in out + err and "a start-up transient; try --start" in out + err
    # the stage identifier's summary too
    code, out, err = run_main(
        "identify",
        "hysteresis",
        tmp_path / "rec.mat",
        *args,
        "--dynamics",
        "0",
        "--creep",
        "none",
        "-o",
        tmp_path / "st.json",
    )
    assert code == 0 and "stage model" in out + err and "a start-up transient; try --start" in out + err
    # validate says the same of a record the model was not fitted on
    code, out, err = run_main(
        "validate", tmp_path / "h3.json", tmp_path / "rec.mat", "--inputs", "Y(3).Data", "--outputs", "Y(1).Data"
    )
    assert code == 0 and "rec.mat  Y(1).Data: max error in the first" in out and "try --start" in out, out + err


# ------------------------------------------------------------------ the shared records
needs_data = pytest.mark.skipif(ds.SHARED_DATA is None, reason="shared data folder ../shared/data not found")


@needs_data
@pytest.mark.parametrize(
    "name",
    ["20_hz_no_lp", "20_hz_lp", "40_hz_no_lp", "100_hz_no_lp", "tri50_1", "tri100_1", "sine50_1", "sine100_1"]
    + ["prbn_1", "bigsine_1"],
)
def test_every_dspace_record_through_the_cli(tmp_path, name):
    path = ds.SHARED_DATA / "piezo_dspace_preisach" / f"{name}.mat"
    if not path.exists():
        pytest.skip(f"{path} not found")
    model = _gain_model(tmp_path / "g.json", 1e-4, ["Y(3).Data"], gain=1.0)
    code, out, err = run_main("simulate", model, path, "-o", tmp_path / "v.csv")
    assert code == 0, err
    exp = ds.load_dspace_piezo(path)
    assert np.array_equal(read_table(tmp_path / "v.csv").column("z"), exp.u[:, 0])


@needs_data
def test_emps_afm_and_daisy_mat_files_through_the_cli(tmp_path):
    emps = ds.SHARED_DATA / "emps" / "DATA_EMPS_PULSES.mat"
    model = _gain_model(tmp_path / "g.json", 1e-3, ["vir"], gain=35.15)
    code, out, err = run_main("simulate", model, emps, "--start", "10", "-o", tmp_path / "f.csv")
    assert code == 0, err
    force = read_table(tmp_path / "f.csv")
    assert force.t0 == pytest.approx(10.0, abs=1e-3) and force.n_samples == 24841 - 10000
    flex = ds.SHARED_DATA / "daisy" / "flexibleStructure.mat"
    model = _gain_model(tmp_path / "f.json", 1 / 1024, ["flexibleStructure_1"], gain=1.0)
    code, out, err = run_main("simulate", model, flex, "--ts", str(1 / 1024), "-o", tmp_path / "x.csv")
    assert code == 0 and read_table(tmp_path / "x.csv").n_samples == 8523, err
    afm = ds.SHARED_DATA / "afm_piezo_stage_frf" / "FRF_data_current_stage2.mat"
    common = ["--order", "8", "--dt", "4e-5", "--fmax", "2000"]
    code, out, err = run_main("identify", "frd", afm, *common, "-o", tmp_path / "afm.json")
    assert "holds 4 frequency responses" in err and "frf.G_uz2stage" in err and code == 2
    code, out, err = run_main("identify", "frd", afm, "--response", "G_uz2stage", *common, "-o", tmp_path / "afm.json")
    assert code == 0, err
    assert json.loads((tmp_path / "afm.json").read_text())["inputs"] == ["uz"]
    # the magnetometer file's (1 x 3) means beside its (18343 x 3) signals: its own test
    # (test_mat_record_lengths.py) reads it through the identification commands


@needs_data
def test_dspace_forc_record_transient_hint_and_window():
    """The 100 Hz FORC record starts with the stage settling onto -90 V: the hint finds it."""
    from stageid.hysteresis import PIIdentifier

    exp = ds.load_dspace_piezo(ds.SHARED_DATA / "piezo_dspace_preisach" / "100_hz_no_lp.mat")
    fit = PIIdentifier(model="pi", n_operators=20).fit(exp)
    (record, edge), *_ = fit.edge_errors
    assert record == 0 and edge.edge == "start" and edge.trim_at < 0.1
    assert fit.max_error_percent[0] > 30  # measured 35.5 %: the transient's first samples
    trimmed = PIIdentifier(model="pi", n_operators=20).fit(
        read_table(ds.SHARED_DATA / "piezo_dspace_preisach" / "100_hz_no_lp.mat")
        .between(start=edge.trim_at)
        .experiment("Y(3).Data", "Y(1).Data")
    )
    # measured: max 35.5 % -> 6.3 % (then at t = 1.995 s, the 100 Hz cycles a rate-independent PI
    # misses), RMS down too; no edge is blamed any more
    assert trimmed.max_error_percent[0] < fit.max_error_percent[0] / 4 and not trimmed.edge_errors
    assert trimmed.rms_error_percent[0] < fit.rms_error_percent[0]
    # the feedforward records end on a sample where the drive was reset: one bad sample, not 5 %
    from stageid.hysteresis.identify.records import align_record

    tri = ds.load_dspace_piezo(ds.SHARED_DATA / "piezo_dspace_preisach" / "tri50_1.mat")
    _, simulated = align_record(trimmed.model, tri.u[:, 0], tri.y[:, 0])
    residual = tri.y[:, 0] - np.ravel(simulated)
    (end,) = edge_errors(residual, float(np.ptp(tri.y[:, 0])), tri.dt, tri.t0)
    assert end.edge == "stop" and end.n_samples <= 5 and end.edge_percent > 30


def test_window_on_the_npz_fast_path_and_refused_for_chunked_records(tmp_path):
    import h5py

    from stageid.data import write_npz

    rng = np.random.default_rng(0)
    u = rng.standard_normal(4096)
    write_npz(tmp_path / "w.npz", {"u": u, "y": np.convolve(u, [0.5, 0.3, 0.1])[:4096]}, dt=DT)
    segments = []
    for window in ((), ("--start", "2.048"), ("--start", "1", "--stop", "3")):
        args = ("frf", tmp_path / "w.npz", "--inputs", "u", "--outputs", "y", "--method", "welch", "--segment", "256")
        code, out, err = run_main(*args, *window, "-o", tmp_path / "fw.csv")
        assert code == 0, err
        segments.append(int(out.split(" segments")[0].rsplit(" ", 1)[1]))
    # half-overlapping 256-sample segments of 4096, 2048 and 2001 samples
    assert segments == [31, 15, 14]
    with h5py.File(tmp_path / "big.h5", "w") as fh:
        fh.attrs["dt"] = DT
        fh["u"], fh["y"] = u, u
    code, out, err = run_main(
        "identify",
        "statespace",
        tmp_path / "big.h5",
        "--inputs",
        "u",
        "--outputs",
        "y",
        "--start",
        "1",
        "-o",
        tmp_path / "m.json",
    )
    _one_line_error(code, out, err, "--start/--stop needs the records in memory")


def test_identify_frd_on_a_mat_frf_struct(tmp_path):
    from stageid.models import load_model

    dt = 1e-3
    f = np.linspace(1.0, 400.0, 120)
    z = np.exp(2j * np.pi * f * dt)
    true = 0.5 / (z - 0.5)  # first-order discrete response, known exactly
    frf = {"w_s": 2 * np.pi * f[None, :], "G_u2y": true[:, None], "G_u2pow": (2 * true)[:, None], "Ts": dt}
    scipy.io.savemat(tmp_path / "meas.mat", {"meas": {"frf": frf}})
    common = ["--order", "1", "--dt", str(dt), "-o", tmp_path / "m.json"]
    line = _one_line_error(*run_main("identify", "frd", tmp_path / "meas.mat", *common), "holds 2 frequency responses")
    assert "frf.G_u2y, frf.G_u2pow" in line and "--response" in line
    _one_line_error(
        *run_main("identify", "frd", tmp_path / "meas.mat", "--response", "G_x", *common),
        "--response 'G_x' is not one of the frequency responses; expected one of frf.G_u2y, frf.G_u2pow",
    )
    code, out, err = run_main("identify", "frd", tmp_path / "meas.mat", "--response", "meas.frf.G_u2y", *common)
    assert code == 0, err
    model = load_model(tmp_path / "m.json")
    assert (model.inputs, model.outputs) == (("u",), ("y",))
    fitted = model.frequency_response(f)[:, 0, 0]
    # noise-free data of the model class: the fit reproduces it to solver precision
    assert np.max(np.abs(fitted - true)) < 1e-6 * np.max(np.abs(true))
