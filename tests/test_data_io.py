"""Readers and writers of stageid.data.io: round trips, property tests and every DataError case."""

from __future__ import annotations

import csv
import io
import os
import re

import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stageid import DataError
from stageid.data import Experiment, Table, files, read_table, write_csv, write_npz
from stageid.data import csv_format as csvf
from stageid.data import io as dio

HYPO = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _bits(a: np.ndarray) -> np.ndarray:
    """Bit pattern of float64 values: equality here means exact round trip (incl. -0.0)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def _write_text(path, text: str) -> str:
    with open(path, "w", newline="") as fh:
        fh.write(text)
    return str(path)


# ----------------------------------------------------------------- strategies
_NAME_CHARS = "abcdefghijklmnopqrstuvwxyzABCXYZ0123456789_-. \"'[]"  # no comma: names must be selectable
names_st = st.text(alphabet=_NAME_CHARS, min_size=1, max_size=12).filter(
    lambda s: (
        s == s.strip() and s != "t" and not csvf.UNIT_RE.match(s) and not csvf.is_number(s) and not files.is_dunder(s)
    )
)


@st.composite
def tables(draw):
    n_cols = draw(st.integers(1, 4))
    names = draw(st.lists(names_st, min_size=n_cols, max_size=n_cols, unique=True))
    n = draw(st.integers(1, 30))
    values = draw(
        hnp.arrays(np.float64, (n, n_cols), elements=st.floats(allow_nan=False, allow_infinity=False, width=64))
    )
    dt = draw(st.floats(1e-4, 10.0))
    t0 = draw(st.floats(-1e3, 1e3))
    return names, values, dt, t0


# ----------------------------------------------------------------- round trips
@HYPO
@given(tables())
def test_csv_round_trip_is_exact(tmp_path, case):
    names, values, dt, t0 = case
    path = tmp_path / "x.csv"
    write_csv(path, {n: values[:, j] for j, n in enumerate(names)}, dt=dt, t0=t0)
    table = read_table(path, ts=dt if values.shape[0] == 1 else None)
    assert table.names == tuple(names)
    assert np.array_equal(_bits(table.values), _bits(values))
    # dt is re-estimated from the written time stamps t0 + dt*k: equal to rounding (~1e-12 relative)
    assert table.dt == pytest.approx(dt, rel=1e-9)
    assert table.t0 == t0


@HYPO
@given(tables())
def test_npz_round_trip_is_exact(tmp_path, case):
    names, values, dt, t0 = case
    path = tmp_path / "x.npz"
    write_npz(path, Table(names, values, dt=dt, t0=t0, units=["V"] * len(names)))
    table = read_table(path, ts=dt if values.shape[0] == 1 else None)
    assert table.names == tuple(names)
    assert table.units == ("V",) * len(names)
    assert np.array_equal(_bits(table.values), _bits(values))
    assert table.dt == pytest.approx(dt, rel=1e-9)


@HYPO
@given(tables(), st.data())
def test_csv_reports_inserted_nan_with_column_and_row(tmp_path, case, data):
    names, values, dt, _ = case
    row = data.draw(st.integers(0, values.shape[0] - 1))
    col = data.draw(st.integers(0, values.shape[1] - 1))
    bad = data.draw(st.sampled_from(["nan", "NaN", "inf", "-inf"]))
    header = io.StringIO()
    csv.writer(header, lineterminator="").writerow(names)
    lines = [header.getvalue()]
    for i, r in enumerate(values):
        cells = [repr(float(v)) for v in r]
        if i == row:
            cells[col] = bad
        lines.append(",".join(cells))
    path = _write_text(tmp_path / "nan.csv", "\n".join(lines) + "\n")
    what = "NaN" if bad.lower() == "nan" else "inf"
    with pytest.raises(DataError, match=re.escape(f"column '{names[col]}' has {what} at row {row}")):
        read_table(path, ts=dt)


@HYPO
@given(tables(), st.data())
def test_npz_reports_inserted_nan_with_column_and_row(tmp_path, case, data):
    names, values, dt, _ = case
    row = data.draw(st.integers(0, values.shape[0] - 1))
    col = data.draw(st.integers(0, values.shape[1] - 1))
    values = values.copy()
    values[row, col] = np.nan
    path = tmp_path / "nan.npz"
    np.savez(path, **{n: values[:, j] for j, n in enumerate(names)})
    with pytest.raises(DataError, match=re.escape(f"column '{names[col]}' has NaN at row {row}")):
        read_table(path, ts=dt)


def test_experiment_round_trip_through_csv_and_npz(tmp_path):
    rng = np.random.default_rng(1)
    exp = Experiment(
        u=rng.standard_normal((50, 2)),
        y=rng.standard_normal((50, 1)),
        dt=2e-4,
        input_names=("Vx", "Vy"),
        output_names=("y",),
        input_units=("V", "V"),
        output_units=("um",),
        t0=1.5,
        name="run1",
    )
    for suffix, writer in ((".csv", write_csv), (".npz", write_npz)):
        path = tmp_path / f"run1{suffix}"
        assert writer(path, exp) == path
        back = read_table(path).experiment(inputs=["Vx", "Vy"], outputs=["y"], name="run1")
        assert np.array_equal(back.u, exp.u) and np.array_equal(back.y, exp.y)
        assert back.dt == pytest.approx(exp.dt, rel=1e-9)  # re-estimated from t stamps
        assert back.t0 == exp.t0
        assert back.input_units == ("V", "V") and back.output_units == ("um",)
        assert back.name == "run1"


def test_csv_header_layout_and_time_first(tmp_path):
    path = tmp_path / "x.csv"
    write_csv(path, Table(["V", "y"], [[1.0, 0.1], [2.0, 0.2]], dt=0.5, units=["V", "um"]))
    lines = open(path).read().splitlines()
    assert lines[0] == "t,V [V],y [um]"
    assert lines[1] == "0,1,0.10000000000000001"
    assert lines[2].startswith("0.5,2,")


def test_csv_without_time_when_dt_unknown(tmp_path):
    path = tmp_path / "x.csv"
    write_csv(path, {"a": [1.0, 2.0], "b": [3.0, 4.0]})
    assert open(path).read().splitlines()[0] == "a,b"
    with pytest.raises(DataError, match="no time column 't'; pass `ts=`"):
        read_table(path)
    table = read_table(path, ts=0.25)
    assert table.dt == 0.25 and table.t0 == 0.0


def test_write_mapping_with_time_column(tmp_path):
    t = 3.0 + 0.01 * np.arange(5)
    path = write_csv(tmp_path / "x.csv", {"t": t, "u": np.arange(5.0)})
    table = read_table(path)
    assert table.names == ("u",) and table.t0 == 3.0 and table.dt == pytest.approx(0.01, rel=1e-12)
    with pytest.raises(DataError, match="disagrees"):
        write_csv(tmp_path / "y.csv", {"t": t, "u": np.arange(5.0)}, dt=0.02)
    with pytest.raises(DataError, match="not uniform"):
        write_csv(tmp_path / "z.csv", {"t": [0.0, 1.0, 3.0], "u": [1.0, 2.0, 3.0]})


def test_caller_arrays_are_never_modified_or_aliased(tmp_path):
    u = np.arange(6.0)
    y2d = np.arange(6.0)[:, None] * 2
    u_before, y_before = u.copy(), y2d.copy()
    write_csv(tmp_path / "a.csv", {"u": u, "y": y2d}, dt=1.0)
    write_npz(tmp_path / "a.npz", {"u": u, "y": y2d}, dt=1.0)
    table = Table(["u", "y"], np.column_stack([u, y2d[:, 0]]), dt=1.0)
    assert np.array_equal(u, u_before) and np.array_equal(y2d, y_before)
    assert u.flags.writeable and y2d.flags.writeable
    values = np.ones((3, 1))
    t2 = Table(["a"], values, dt=1.0)
    values[0, 0] = 5.0  # the table holds its own copy
    assert t2.values[0, 0] == 1.0
    with pytest.raises(ValueError):
        table.values[0, 0] = 1.0  # read-only
    exp = read_table(tmp_path / "a.csv").experiment(["u"], ["y"])
    assert np.array_equal(exp.u[:, 0], u_before)


def test_atomic_write_leaves_old_file_when_writing_fails(tmp_path, monkeypatch):
    path = tmp_path / "keep.csv"
    write_csv(path, {"u": [1.0, 2.0]}, dt=1.0)
    before = path.read_bytes()

    def broken_rows(fh, *args, **kwargs):
        fh.write("0,1\n0.5,")  # half a file, then the disk "fails"
        raise OSError("disk full")

    monkeypatch.setattr(csvf, "_write_rows", broken_rows)
    with pytest.raises(OSError, match="disk full"):
        write_csv(path, {"u": [7.0, 8.0, 9.0]}, dt=1.0)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["keep.csv"]  # no temp file left behind


def test_written_file_permissions_follow_umask(tmp_path):
    path = write_csv(tmp_path / "p.csv", {"u": [1.0]}, dt=1.0)
    umask = os.umask(0)
    os.umask(umask)
    assert (path.stat().st_mode & 0o777) == (0o666 & ~umask)


def test_write_errors(tmp_path):
    cases = [
        ({"u": [1.0, np.nan]}, {"dt": 1.0}, r"column 'u' has NaN at row 1"),
        ({"u": [1.0, 2.0], "y": [1.0]}, {}, r"unequal lengths: 'u' has 2 rows and 'y' has 1"),
        ({"u": np.ones((3, 2))}, {}, r"column 'u' must have shape \(n_samples,\)"),
        ({"u": ["a", "b"]}, {}, r"column 'u' must hold real numbers"),
        ({" u": [1.0]}, {}, r"without surrounding whitespace"),
        ({"u [V]": [1.0]}, {}, r"would be read back as a name with a unit"),
        ({"1": [1.0], "2.5": [2.0]}, {}, r"look like numbers"),
        ({}, {}, r"at least one column"),
        ({"u": [1.0]}, {"dt": -1.0}, r"`dt` must be a positive number"),
    ]
    for data, kw, message in cases:
        with pytest.raises(DataError, match=message):
            write_csv(tmp_path / "w.csv", data, **kw)
    with pytest.raises(DataError, match="taken from the Table"):
        write_csv(tmp_path / "w.csv", Table(["a"], [1.0], dt=1.0), dt=2.0)
    with pytest.raises(DataError, match="directory .* does not exist"):
        write_csv(tmp_path / "missing" / "w.csv", {"u": [1.0]})
    with pytest.raises(DataError, match="reserved for metadata"):
        write_npz(tmp_path / "w.npz", {"__x__": [1.0]})
    assert not any(p.name.startswith(".w.") for p in tmp_path.iterdir())


# ----------------------------------------------------------------- CSV parsing
def test_csv_variants_units_delimiters_line_endings(tmp_path):
    text = '\ufefft [s],"V [V]",y [um]\r\n0,1,2\r\n\r\n0.001,3,4\r\n0.002,5,6\r\n'
    path = tmp_path / "units.csv"
    path.write_bytes(text.encode("utf-8"))
    table = read_table(path)
    assert table.names == ("V", "y") and table.units == ("V", "um")
    assert table.n_samples == 3 and table.dt == pytest.approx(0.001, rel=1e-12)
    assert np.array_equal(table.column("y"), [2.0, 4.0, 6.0])
    for delim in ("\t", ";"):
        p = _write_text(tmp_path / "d.csv", f"a{delim}b\n1{delim}2\n3{delim}4\n")
        assert np.array_equal(read_table(p, ts=1.0).values, [[1, 2], [3, 4]])


def test_csv_ts_with_time_column(tmp_path):
    path = _write_text(tmp_path / "x.csv", "t,u\n0,1\n0.1,2\n0.2,3\n")
    assert read_table(path, ts=0.1).dt == 0.1  # agrees: the caller's nominal value is used
    with pytest.raises(DataError, match=r"ts=0.2 s disagrees with the period 0.1 s of the time column 't'"):
        read_table(path, ts=0.2)
    with pytest.raises(DataError, match=r"`ts` must be a positive number of seconds; got -1"):
        read_table(path, ts=-1)


def test_time_jitter_tolerance(tmp_path):
    t = 1e-3 * np.arange(100)
    t[40] += 1e-3 * 1e-4  # a jitter of 1e-4 dt, typical for single-precision loggers
    text = "t,u\n" + "".join(f"{float(v)!r},0\n" for v in t)
    path = _write_text(tmp_path / "j.csv", text)
    # the one sample-time rule accepts it (UNIFORM_RTOL = 1e-3) and measures it; a caller may be stricter
    assert read_table(path).jitter == pytest.approx(1e-4, rel=1e-3)
    with pytest.raises(DataError, match=r"not uniform: the stamp at row 40 .* within 1e-06 of the period"):
        read_table(path, time_rtol=1e-6)
    for bad in (-1e-3, 1.0, float("nan"), "1e-3"):
        with pytest.raises(DataError, match=r"`time_rtol` must be a number in \[0, 1\)"):
            read_table(path, time_rtol=bad)


@pytest.mark.parametrize(
    "text, message",
    [
        ("u,y1,y2\n" + "1,2,3\n" * 17 + "1,2,nan\n", r"column 'y2' has NaN at row 17 \(data rows counted from 0\)"),
        ("u,y\n1,2\n1,-inf\n", r"column 'y' has inf at row 1"),
        ("t,u\n0,1\n0.1,nan\n", r"column 'u' has NaN at row 1"),
        ("t,u\nnan,1\n0.1,1\n", r"column 't' has NaN at row 0"),
        ("u,v\n" + "1,2\n" * 5 + "abc,2\n", r"column 'u' row 5: 'abc' is not a number \(file 'bad.csv', line 7"),
        ("u,v\n1,2\n\n3,x\n", r"column 'v' row 1: 'x' is not a number \(file 'bad.csv', line 4"),
        ("u,v\n1,2\n3,\n", r"column 'v' row 1: empty cell is not a number"),
        ("u,v\n1,2\n3,4,5\n", r"row 1 \(file line 3\) has 3 fields; expected 2"),
        ("u,v\n1,2\n3\n", r"row 1 \(file line 3\) has 1 fields; expected 2"),
        ("u,v\n1,2,3\n4,5,6\n", r"the header has 2 columns but the data rows have 3 fields"),
        ("t,u\n0,1\n0.1,1\n0.1,1\n", r"'t' must be strictly increasing; row 2 has t=0.1 after t=0.1 at row 1"),
        ("t,u\n0,1\n0.2,1\n0.1,1\n", r"'t' must be strictly increasing; row 2"),
        ("t,u\n0,1\n0.1,1\n0.2,1\n0.35,1\n0.4,1\n", r"'t' is not uniform: the stamp at row 3 "),
        ("t,u\n0,1\n", r"single sample, so dt is unknown"),
        ("t [ms],u\n0,1\n1,1\n", r"time column 't' must be in seconds; got unit 'ms'"),
        ("t\n0\n1\n", r"only a time column"),
        ("u,u\n1,2\n", r"duplicate column name 'u' \(columns 0 and 1\)"),
        ("u, u \n1,2\n", r"duplicate column name 'u'"),
        ("u,,y\n1,2,3\n", r"header column 1 is empty"),
        ("1.0,2.0\n3.0,4.0\n", r"has no header row; expected column names in the first line"),
        ("u,v\n", r"has a header but no data rows"),
        ("\n\n", r"has no header row"),
        ("", r"is empty"),
    ],
)
def test_csv_errors(tmp_path, text, message):
    path = _write_text(tmp_path / "bad.csv", text)
    with pytest.raises(DataError, match=message) as info:
        read_table(path, ts=None if text.startswith("t") else 0.1)
    assert "\n" not in str(info.value)  # one-line messages
    assert isinstance(info.value, ValueError)


def test_files_that_are_not_what_their_extension_says(tmp_path):
    npz = tmp_path / "real.npz"
    np.savez(npz, u=np.zeros(3))
    binary_csv = tmp_path / "x.csv"
    binary_csv.write_bytes(npz.read_bytes())
    with pytest.raises(
        DataError, match=r"file 'x.csv' is not a text CSV file: it contains binary data \(it looks like a zip"
    ):
        read_table(binary_csv, ts=1.0)
    latin = tmp_path / "l.csv"
    latin.write_bytes(b"u\xff\xfe,v\n1,2\n")
    with pytest.raises(DataError, match=r"is not a UTF-8 text CSV file"):
        read_table(latin, ts=1.0)
    text_npz = _write_text(tmp_path / "x.npz", "u,v\n1,2\n")
    with pytest.raises(DataError, match=r"^file 'x.npz' is not a NumPy .npz archive\.$"):
        read_table(text_npz)
    npy = tmp_path / "a.npz"
    with open(npy, "wb") as fh:
        np.save(fh, np.zeros(3))
    with pytest.raises(DataError, match=r"not a NumPy .npz archive \(it looks like a NumPy .npy array\)"):
        read_table(npy)
    broken_zip = tmp_path / "broken.npz"
    broken_zip.write_bytes(b"PK\x03\x04" + b"\x00" * 40)
    with pytest.raises(DataError, match=r"not a readable NumPy .npz archive"):
        read_table(broken_zip)
    text_mat = _write_text(tmp_path / "x.mat", "u,v\n1,2\n")
    with pytest.raises(DataError, match=r"file 'x.mat' is not a MATLAB .mat file"):
        read_table(text_mat)
    junk_mat = tmp_path / "j.mat"
    junk_mat.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(DataError, match=r"file 'j.mat' is not a readable MATLAB .mat file"):
        read_table(junk_mat)


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(DataError, match=r"file '.*nope.csv' does not exist"):
        read_table(tmp_path / "nope.csv", ts=1.0)
    with pytest.raises(DataError, match=r"is not a file"):
        dio.read_csv(tmp_path, ts=1.0)
    with pytest.raises(DataError, match=r"extension '.txt'; expected one of .csv, .npz, .mat"):
        read_table(tmp_path / "x.txt")


# ----------------------------------------------------------------- NPZ
def test_npz_columns_matrices_and_errors(tmp_path):
    p = tmp_path / "m.npz"
    np.savez(p, t=0.5 * np.arange(4), u=np.arange(4), y=np.ones((4, 2)), z=np.zeros((4, 1)), __meta__=np.zeros(2))
    table = read_table(p)
    assert table.names == ("u", "y_1", "y_2", "z") and table.dt == 0.5
    assert table.units == ("",) * 4
    cases = [
        ({"u": np.zeros(4), "v": np.zeros(3)}, r"unequal lengths: 'u' has 4 rows and 'v' has 3"),
        ({"u": np.zeros(4) + 1j}, r"array 'u' has dtype complex128; expected real numbers"),
        ({"u": np.array(["a", "b"])}, r"array 'u' has dtype <U1"),
        ({"u": np.zeros((2, 2, 2))}, r"array 'u' has shape \(2, 2, 2\)"),
        ({"u": np.array(1.0)}, r"array 'u' has shape \(\)"),
        ({"u": np.zeros(0)}, r"no data rows"),
        ({"__only__": np.zeros(3)}, r"holds no arrays"),
        ({"y": np.ones((3, 2)), "y_1": np.zeros(3)}, r"duplicate column name 'y_1'"),
    ]
    for arrays, message in cases:
        np.savez(p, **arrays)
        with pytest.raises(DataError, match=message):
            read_table(p, ts=1.0)
    np.savez(p, u=np.array([object(), 1], dtype=object))
    with pytest.raises(DataError, match=r"array 'u' holds Python objects"):
        read_table(p, ts=1.0)


# ----------------------------------------------------------------- MAT
def test_mat_v5_columns(tmp_path):
    p = tmp_path / "m.mat"
    n = 6
    scipy.io.savemat(
        p,
        {
            "t": (0.01 * np.arange(n))[:, None],
            "u": np.arange(n, dtype=float)[None, :],  # row vector: still a column
            "y": np.ones((n, 2)),
            "pulses": np.zeros((n, 1), dtype=np.uint8),
            "gain": 3.0,
            "label": "hello",
            "settings": {"kp": 1.0, "kv": 2.0},
        },
    )
    table = read_table(p)
    assert table.names == ("u", "y_1", "y_2", "pulses")
    assert table.dt == pytest.approx(0.01, rel=1e-12)
    assert np.array_equal(table.column("u"), np.arange(n))
    scipy.io.savemat(p, {"s": {"gain": 2.0, "label": "run 1"}})
    with pytest.raises(DataError, match=r"holds no numeric signals .*; found only label \(text\), gain \(scalar\)\.$"):
        read_table(p, ts=1.0)
    scipy.io.savemat(p, {"a": np.ones((5, 1)), "b": np.ones((4, 1))})
    with pytest.raises(DataError, match=r"unequal lengths \(5 samples: a; 4 samples: b\)"):
        read_table(p, ts=1.0)
    scipy.io.savemat(p, {"a": np.array([[1.0], [np.inf]])})
    with pytest.raises(DataError, match=r"column 'a' has inf at row 1"):
        read_table(p, ts=1.0)


def _write_mat73(path, variables: dict, structs=("s",)):
    """A MATLAB v7.3 file as MATLAB writes it: 512-byte user block, arrays stored transposed."""
    import h5py

    with h5py.File(path, "w", userblock_size=512) as fh:
        for name, arr in variables.items():
            ds = fh.create_dataset(name, data=np.asarray(arr).T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")
        for name in structs:
            g = fh.create_group(name)
            g.attrs["MATLAB_class"] = np.bytes_("struct")
            g.create_dataset("x", data=np.ones((1, 3)))
        ds = fh.create_dataset("title", data=np.frombuffer(b"ab", dtype=np.uint8).astype(np.uint16)[None, :].T)
        ds.attrs["MATLAB_class"] = np.bytes_("char")
    with open(path, "r+b") as fh:
        header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
        fh.write(header.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM")


def test_mat_v73_through_h5py(tmp_path):
    p = tmp_path / "big.mat"
    n = 7
    _write_mat73(
        p,
        {"t": (0.1 * np.arange(n))[:, None], "u": np.arange(n, dtype=float)[:, None], "y": np.ones((n, 2))},
        structs=(),
    )
    table = read_table(p)
    assert table.names == ("u", "y_1", "y_2")
    assert table.dt == pytest.approx(0.1, rel=1e-12)
    assert np.array_equal(table.column("u"), np.arange(n))
    _write_mat73(p, {})  # a struct s with x (1 x 3) beside a char array: the struct's field is a column
    assert read_table(p, ts=1.0).names == ("s.x",)


# ----------------------------------------------------------------- Table
def test_table_experiment_selection_and_errors():
    table = Table(["a", "b", "c"], np.arange(12.0).reshape(4, 3), dt=0.1, t0=2.0, units=["V", "", "um"], source="f.csv")
    exp = table.experiment(inputs="a", outputs=["c", "b"])
    assert exp.input_names == ("a",) and exp.output_names == ("c", "b")
    assert exp.output_units == ("um", "") and exp.t0 == 2.0 and exp.name == "f.csv"
    assert np.array_equal(exp.y[:, 0], [2, 5, 8, 11])
    with pytest.raises(DataError, match=r"^file 'f.csv': unknown column 'X'; expected one of a, b, c$"):
        table.experiment(inputs=["X"], outputs=["a"])
    with pytest.raises(DataError, match=r"^file 'f.csv': unknown column 'X'; expected one of a, b, c$"):
        table.column("X")
    with pytest.raises(DataError, match=r"column 'a' is listed twice \(as input and as output\)"):
        table.experiment(inputs=["a"], outputs=["a"])
    with pytest.raises(DataError, match=r"inputs must name at least one column"):
        table.experiment(inputs=[], outputs=["a"])
    assert np.allclose(table.time, [2.0, 2.1, 2.2, 2.3])


def test_table_validation():
    with pytest.raises(DataError, match=r"at least one named column"):
        Table([], np.zeros((2, 0)))
    with pytest.raises(DataError, match=r"'t' is reserved for the time axis"):
        Table(["t", "u"], np.zeros((2, 2)))
    with pytest.raises(DataError, match=r"must have shape \(n_samples, 2\)"):
        Table(["a", "b"], np.zeros((2, 3)))
    with pytest.raises(DataError, match=r"no data rows"):
        Table(["a"], np.zeros((0, 1)))
    with pytest.raises(DataError, match=r"`units` must have 1 entries"):
        Table(["a"], np.zeros((2, 1)), units=["V", "V"])
    no_dt = Table(["u", "y"], np.zeros((3, 2)))
    with pytest.raises(DataError, match=r"sample time is unknown"):
        no_dt.experiment(["u"], ["y"])
    exp = Experiment(u=np.zeros(3), y=np.zeros(3), dt=1.0, input_names=["x"], output_names=["x"])
    with pytest.raises(DataError, match=r"duplicate column name 'x'"):
        write_csv("unused.csv", exp)


# ----------------------------------------------------------------- regressions of the bug hunt
def test_readers_are_exported_from_stageid_data():
    import stageid.data as data

    assert data.read_csv is dio.read_csv and data.read_npz is dio.read_npz and data.read_mat is dio.read_mat
    assert {"read_csv", "read_npz", "read_mat", "write_csv", "write_npz"} <= set(data.__all__)


@pytest.mark.parametrize("name", ["Z;1", "a\tb"])
def test_write_csv_refuses_names_that_would_split_the_header(tmp_path, name):
    # one column without a time axis: the reader would take ';' / tab as the delimiter
    path = tmp_path / "s.csv"
    with pytest.raises(DataError, match=r"column name .* would not read back from CSV") as err:
        write_csv(path, {name: np.arange(3.0)})
    assert "\n" not in str(err.value)
    assert not path.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["Z;1", "a\tb", 'q"x'])
def test_write_csv_names_that_read_back_are_kept(tmp_path, name):
    path = tmp_path / "s.csv"
    write_csv(path, {name: np.arange(3.0), "y": np.ones(3)}, dt=0.5)
    assert read_table(path).names == (name, "y")


def test_epoch_time_stamps_at_10_khz_read_back(tmp_path):
    # float64 spacing at 1.7e9 s is 2.4e-7 s, 0.24 % of the 1e-4 s step: steps differ by that
    n, dt = 20000, 1e-4
    t = 1.7e9 + dt * np.arange(n)
    assert np.ptp(np.diff(t)) > 1e-6 * dt  # the jitter the old check rejected
    u = np.random.default_rng(3).standard_normal(n)
    write_csv(tmp_path / "epoch.csv", {"t": t, "u": u})
    table = read_table(tmp_path / "epoch.csv")
    # the mean step inherits the stamps' rounding spread over n - 1 steps: 2.4e-7 / 2e4 = 1.2e-11 s
    assert table.t0 == 1.7e9 and table.dt == pytest.approx(dt, rel=1e-6)
    assert np.array_equal(table.column("u"), u)
    write_npz(tmp_path / "epoch.npz", {"t": t, "u": u})
    assert read_table(tmp_path / "epoch.npz").dt == pytest.approx(dt, rel=1e-6)


def test_epoch_time_stamps_still_reject_a_real_glitch(tmp_path):
    t = 1.7e9 + 1e-4 * np.arange(2000)
    t[700] += 3e-6  # 3 % of a step: far above the 2.4e-7 s rounding of the stamps
    np.savez(tmp_path / "g.npz", t=t, u=np.zeros(2000))
    with pytest.raises(DataError, match=r"time column 't' is not uniform: the stamp at row 700 "):
        read_table(tmp_path / "g.npz")


@pytest.mark.parametrize("writer", [write_csv, write_npz])
def test_column_names_with_commas_are_refused_on_writing(tmp_path, writer):
    # column lists on the command line (--inputs a,b) are split at commas: such a column could
    # be written but never selected again, so no writer accepts one
    path = tmp_path / ("s.csv" if writer is write_csv else "s.npz")
    with pytest.raises(DataError, match=r"column name 'a,b' contains ','"):
        writer(path, {"a,b": np.arange(3.0), "y": np.ones(3)}, dt=0.5)
    assert not list(tmp_path.iterdir())


def test_huge_finite_samples_read_but_are_refused_as_identification_data(tmp_path):
    # a file may hold any finite float64; an Experiment (what every estimator fits) says why
    # 1e308 cannot be used instead of failing later with an unrelated message
    path = tmp_path / "big.csv"
    path.write_text("t,u,y\n0,1,2\n1,1e308,3\n2,1,2\n")
    table = read_table(path)
    with pytest.raises(DataError, match=r"input column 'u' has 1e\+308 at row 1; expected magnitudes below 1e\+150"):
        table.experiment(inputs=["u"], outputs=["y"])


@pytest.mark.filterwarnings("error::RuntimeWarning")  # an overflowing sum is not the user's news
def test_sample_check_finds_the_first_bad_sample_whatever_the_sum_does():
    # check_samples decides by the sum first: a sum that overflows with every sample finite
    # must pass, and a NaN or a too large sample of either sign must still be found and placed
    from stageid.data.experiment import check_samples

    big = np.array([[1e308, 1.0], [1e308, 2.0]])  # finite samples, infinite sum
    check_samples(big, ["a", "b"], max_abs=np.inf)
    with pytest.raises(DataError, match=r"column 'a' has 1e\+308 at row 0"):
        check_samples(big, ["a", "b"])
    low = np.array([[1.0, 2.0], [3.0, -1e200]])
    with pytest.raises(DataError, match=r"column 'b' has -1e\+200 at row 1"):
        check_samples(low, ["a", "b"])
    both = np.array([[1e308, 1e308], [1.0, np.nan]])
    with pytest.raises(DataError, match=r"column 'b' has NaN at row 1"):
        check_samples(both, ["a", "b"], max_abs=np.inf)
    check_samples(np.zeros((0, 2)), ["a", "b"])


def test_a_header_longer_than_the_sniffed_bytes_is_read_whole(tmp_path):
    name = "x" * 70000
    path = tmp_path / "long.csv"
    path.write_text(f"t,{name},y\n0,1,2\n1,1,2\n")
    assert read_table(path).names == (name, "y")
