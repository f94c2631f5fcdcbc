"""``identify statespace`` and ``frf`` on chunked records (HDF5, Zarr, .npy): the result the
in-memory command gives, and bad chunked files refused in one line, exit 2, no output."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from _chunked_data import DT, columns, write
from conftest import assert_one_line_error, run_main
from stageid.data import write_csv
from stageid.models import load_model

N = 6000
IO = ("--inputs", "u1,u2", "--outputs", "y1,y2")


@pytest.fixture(scope="module")
def x():
    return columns(N, seed=5)


def _csv(folder, x):
    path = folder / "rec.csv"
    write_csv(path, {n: c for n, c in zip(("u1", "u2", "y1", "y2"), x.T)}, dt=DT)
    return path


@pytest.mark.parametrize("fmt", ["h5", "zarr", "npy-folder"])
def test_identify_statespace_on_a_chunked_record_equals_the_csv(tmp_path, x, fmt):
    # a chunked fit is the realisation of the chunk-by-chunk posterior: the in-memory fit's without
    # the output-error refinement, which needs the records in memory
    from stageid.data import read_table
    from stageid.subspace import HankelMAP

    path = write(tmp_path, fmt, x)
    args = ("identify", "statespace", *IO, "--order", "4", "--horizon", "8", "--band", "0:450")
    rc, _, err = run_main(*args, path, "-o", tmp_path / "chunked.json")
    assert rc == 0, err
    exp = read_table(_csv(tmp_path, x)).experiment(list(IO[1].split(",")), list(IO[3].split(",")))
    memory = HankelMAP(order=4, horizon=8, band=(0.0, 450.0), output_error=False).fit(exp).model
    f = np.linspace(1.0, 450.0, 40)
    got = load_model(tmp_path / "chunked.json").frequency_response(f)
    want = memory.frequency_response(f)
    # the CSV holds the samples to 17 significant digits: the same statistics to ~1e-15
    assert np.max(np.abs(got - want)) / np.max(np.abs(want)) < 1e-7


def test_uncertainty_of_a_chunked_fit_equals_the_in_memory_one(tmp_path, x):
    # the posterior and the lag statistics a result keeps come from the chunk-by-chunk sums, so
    # its bands must be the in-memory fit's, overlapping-window covariance included
    from stageid.data import read_table
    from stageid.subspace import HankelMAP
    from stageid.subspace.uncertainty import realised_response_uncertainty

    path = write(tmp_path, "h5", x)
    args = ("identify", "statespace", *IO, "--order", "4", "--horizon", "8", "--band", "0:450")
    grid = ("--uncertainty-grid", "1:450:30")
    rc, _, err = run_main(*args, path, "-o", tmp_path / "c.json", "--uncertainty", tmp_path / "c.csv", *grid)
    assert rc == 0, err
    exp = read_table(_csv(tmp_path, x)).experiment(list(IO[1].split(",")), list(IO[3].split(",")))
    res = HankelMAP(order=4, horizon=8, band=(0.0, 450.0), output_error=False).fit(exp)  # as a chunked fit
    assert res.channels[0].window_lags is not None  # the in-memory fit uses the lags, not the p P allowance
    fr = realised_response_uncertainty(res, np.geomspace(1, 450, 30))
    want = fr.to_columns()
    got = np.genfromtxt(tmp_path / "c.csv", delimiter=",", names=True)
    assert set(got.dtype.names) == set(want) and any(n.startswith("std_") for n in want)
    for name in want:
        np.testing.assert_allclose(got[name], want[name], rtol=1e-6, atol=1e-12 * np.max(np.abs(want[name])))


def test_npy_matrix_needs_ts_and_names_its_columns(tmp_path, x):
    path = write(tmp_path, "npy", x)
    base = ("identify", "statespace", path, "--inputs", "rec_1,rec_2", "--outputs", "rec_3,rec_4", "--order", "4")
    rc, _, err = run_main(*base, "--horizon", "8", "-o", tmp_path / "m.json")
    assert_one_line_error(rc, err, "no sample time", "--ts")
    assert not (tmp_path / "m.json").exists()
    rc, _, err = run_main(*base, "--horizon", "8", "--ts", DT, "-o", tmp_path / "m.json")
    assert rc == 0, err
    assert json.loads((tmp_path / "m.json").read_text())["inputs"] == ["rec_1", "rec_2"]


def test_frf_welch_on_a_chunked_record_equals_the_csv(tmp_path, x):
    path = write(tmp_path, "h5-t", x)
    rc, _, err = run_main("frf", path, *IO, "--segment", "512", "-o", tmp_path / "chunked.csv")
    assert rc == 0, err
    rc, _, err = run_main("frf", _csv(tmp_path, x), *IO, "--segment", "512", "-o", tmp_path / "memory.csv")
    assert rc == 0, err
    got = np.genfromtxt(tmp_path / "chunked.csv", delimiter=",", names=True)
    want = np.genfromtxt(tmp_path / "memory.csv", delimiter=",", names=True)
    assert got.dtype.names == want.dtype.names
    for name in want.dtype.names:
        np.testing.assert_allclose(got[name], want[name], rtol=1e-9, atol=1e-12 * np.max(np.abs(want[name])))


@pytest.mark.parametrize("method", ["lpm", "periodic"])
def test_frf_methods_that_need_the_record_refuse_it(tmp_path, x, method):
    path = write(tmp_path, "h5", x)
    extra = ("--periods", "4") if method == "periodic" else ()
    rc, _, err = run_main("frf", path, *IO, "--method", method, *extra, "-o", tmp_path / "f.csv")
    assert_one_line_error(rc, err, f"--method {method}", "in memory")
    assert not (tmp_path / "f.csv").exists()


def _bad_h5(path, case):
    n = 500
    with h5py.File(path, "w") as f:
        if case != "no dt":
            f.attrs["dt"] = DT
        f["u1"] = np.ones(n)
        f["u2"] = np.zeros(n) if case != "empty" else np.zeros(0)
        f["y1"] = np.zeros(n + 1 if case == "lengths" else n)
        f["y2"] = np.zeros((n, 2)) if case == "2-D" else np.zeros(n)


@pytest.mark.parametrize(
    "case, fragments",
    [
        ("lengths", ("column 'y1' has 501 samples", "equal lengths")),
        ("no dt", ("no sample time", "'dt' attribute", "--ts")),
        ("missing", ("no column 'y3'", "u1, u2, y1, y2")),
        ("empty", ("column 'u2' is empty",)),
        ("2-D", ("column 'y2' has shape (500, 2)", "1-D")),
    ],
)
@pytest.mark.parametrize("command", ["statespace", "frf"])
def test_bad_chunked_file_is_one_line_exit_2_no_file(tmp_path, case, fragments, command):
    path = tmp_path / "bad.h5"
    _bad_h5(path, case)
    outs = "y1,y3" if case == "missing" else "y1,y2"
    out = tmp_path / ("m.json" if command == "statespace" else "f.csv")
    head = ("identify", "statespace", "--order", "2") if command == "statespace" else ("frf",)
    rc, _, err = run_main(*head, path, "--inputs", "u1,u2", "--outputs", outs, "-o", out)
    assert_one_line_error(rc, err, *fragments)
    assert not out.exists()


def test_bad_zarr_and_npy_inputs(tmp_path, x):
    import zarr

    store = tmp_path / "bad.zarr"
    g = zarr.open_group(str(store), mode="w")
    g.create_array("u1", shape=(10,), dtype="f8")[:] = 1.0
    g.create_array("y1", shape=(11,), dtype="f8")[:] = 1.0
    rc, _, err = run_main("frf", store, "--inputs", "u1", "--outputs", "y1", "--ts", DT, "-o", tmp_path / "f.csv")
    assert_one_line_error(rc, err, "column 'y1' has 11 samples", "equal lengths")
    folder = tmp_path / "empty_folder"
    folder.mkdir()
    rc, _, err = run_main("frf", folder, "--inputs", "u1", "--outputs", "y1", "--ts", DT, "-o", tmp_path / "f.csv")
    assert_one_line_error(rc, err, "neither a Zarr store nor a folder of .npy")
    bad = np.array(x)
    bad[4321, 2] = np.nan
    path = write(tmp_path, "h5", bad)
    rc, _, err = run_main(
        "identify", "statespace", path, *IO, "--order", "2", "--horizon", "8", "-o", tmp_path / "m.json"
    )
    assert_one_line_error(rc, err, "column 'y1' has NaN at row 4321")
    assert not (tmp_path / "m.json").exists() and not (tmp_path / "f.csv").exists()


def test_chunked_settings_that_need_memory_are_refused(tmp_path, x):
    path = write(tmp_path, "h5", x)
    base = ("identify", "statespace", path, *IO, "-o", tmp_path / "m.json")
    rc, _, err = run_main(*base, "--order", "4", "--per-channel")
    assert_one_line_error(rc, err, "drop --per-channel")
    rc, _, err = run_main(*base, "--order", "4", "--report", tmp_path / "rep")
    assert_one_line_error(rc, err, "--report needs the records in memory")
    rc, _, err = run_main(*base[:3], _csv(tmp_path, x), *IO, "--order", "4", "-o", tmp_path / "m.json")
    assert_one_line_error(rc, err, "on its own", "expected one")
    assert not (tmp_path / "m.json").exists()


def test_unreachable_scheduler_is_one_line(tmp_path, x):
    path = write(tmp_path, "h5", x)
    rc, _, err = run_main("frf", path, *IO, "--scheduler", "tcp://127.0.0.1:9", "-o", tmp_path / "f.csv")
    assert_one_line_error(rc, err, "cannot reach the Dask scheduler")
    assert not (tmp_path / "f.csv").exists()

    rc, _, err = run_main("frf", _csv(tmp_path, x), *IO, "--scheduler", "tcp://127.0.0.1:9", "-o", tmp_path / "f.csv")
    assert_one_line_error(rc, err, "--scheduler", "chunked record")
