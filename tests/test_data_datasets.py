"""Loaders of the shared real data: synthetic files of the same structure always, the real
files (../shared/data) when present, checked against the shapes and sample times of
shared/data/README.md."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from stageid import DataError
from stageid.data import Table, read_table
from stageid.data import datasets as ds

needs_shared = pytest.mark.skipif(
    ds.SHARED_DATA is None,
    reason="shared data folder not found (set STAGEID_SHARED_DATA or place it at <repo>/../shared/data)",
)


# ----------------------------------------------------------------- folder resolution
def test_shared_data_dir_env_var(tmp_path, monkeypatch):
    monkeypatch.setenv(ds.ENV_VAR, str(tmp_path))
    assert ds.shared_data_dir() == tmp_path
    monkeypatch.setenv(ds.ENV_VAR, str(tmp_path / "absent"))
    assert ds.shared_data_dir() is None
    monkeypatch.delenv(ds.ENV_VAR)
    found = ds.shared_data_dir()
    assert found is None or (found.is_dir() and found.parts[-2:] == ("shared", "data"))


def test_load_daisy_without_shared_folder(monkeypatch, tmp_path):
    monkeypatch.setenv(ds.ENV_VAR, str(tmp_path / "absent"))
    with pytest.raises(DataError, match=r"shared data folder was not found; set STAGEID_SHARED_DATA"):
        ds.load_daisy("ballbeam")
    with pytest.raises(DataError, match=r"unknown DaISy set 'nope'; expected one of cd_player_arm, flexible_structure"):
        ds.load_daisy("nope")


# ----------------------------------------------------------------- synthetic files
def _dspace_struct(n: int, dt: float = 1e-4) -> dict:
    t = (dt * np.arange(n)).astype(np.float32).astype(float)  # single-precision stamps, like dSPACE
    volt = 90.0 * np.sin(np.linspace(0, 6, n))
    disp = 0.04 * volt
    y = np.zeros((1, 3), dtype=[("Name", object), ("Data", object), ("Unit", object)])
    for i, sig in enumerate((disp, disp, volt)):
        y[0, i] = ("sig", sig[None, :], "")
    x = np.zeros((1, 1), dtype=[("Name", object), ("Data", object)])
    x[0, 0] = ("time", t[None, :])
    cap = np.zeros((1, 1), dtype=[("SamplingPeriod", object), ("Downsampling", object)])
    cap[0, 0] = (np.array([[dt]]), np.array([[1.0]]))
    rec = np.zeros((1, 1), dtype=[("X", object), ("Y", object), ("Capture", object)])
    rec[0, 0] = (x, y, cap)
    return {"hz_no_lp": rec}, volt, disp


def test_load_dspace_piezo_synthetic(tmp_path):
    content, volt, disp = _dspace_struct(5001)
    p = tmp_path / "20_hz_no_lp.mat"
    scipy.io.savemat(p, content)
    exp = ds.load_dspace_piezo(p)
    assert exp.name == "20_hz_no_lp" and exp.dt == 1e-4
    assert exp.input_names == ("V",) and exp.output_names == ("y",)
    assert exp.input_units == ("V",) and exp.output_units == ("um",)
    assert np.array_equal(exp.u[:, 0], volt) and np.array_equal(exp.y[:, 0], disp)
    scipy.io.savemat(p, {**content, "other": np.ones(3)})
    with pytest.raises(DataError, match=r"expected exactly one dSPACE struct variable; got 2"):
        ds.load_dspace_piezo(p)
    scipy.io.savemat(p, {"x": np.ones((3, 1))})
    with pytest.raises(DataError, match=r"variable 'x' is not a dSPACE struct with fields X and Y"):
        ds.load_dspace_piezo(p)
    with pytest.raises(DataError, match=r"does not exist"):
        ds.load_dspace_piezo(tmp_path / "missing.mat")


def test_load_smarthysteresis_synthetic(tmp_path):
    n = 100
    t = 2e-4 * np.arange(n)
    lines = "".join(f",{ti!r},{0.1 * i!r},{-1.0 * i!r}\n" for i, ti in enumerate(t.tolist()))
    p = tmp_path / "h.csv"
    p.write_text(lines)
    exp = ds.load_smarthysteresis(p)
    assert exp.n_samples == n and exp.dt == pytest.approx(2e-4, rel=1e-12)
    assert np.allclose(exp.y[:, 0], 0.1 * np.arange(n)) and np.allclose(exp.u[:, 0], -np.arange(n))
    p.write_text(",0,1,x\n")
    with pytest.raises(DataError, match=r"expected 4 comma-separated fields"):
        ds.load_smarthysteresis(p)
    p.write_text(",0,1,2\n,0.0002,1,2\n,0.0001,1,2\n")
    with pytest.raises(DataError, match=r"strictly increasing"):
        ds.load_smarthysteresis(p)


def test_load_emps_synthetic(tmp_path):
    n = 50
    t = (1e-3 * np.arange(n))[:, None]
    p = tmp_path / "DATA_EMPS_PULSES.mat"
    scipy.io.savemat(
        p,
        {
            "t": t,
            "qm": np.ones((n, 1)),
            "qg": np.zeros((n, 1)),
            "vir": np.arange(n)[:, None] * 1.0,
            "pulses_N": np.zeros((n, 1), dtype=np.uint8),
            "gtau": 35.15,
            "kp": 160.18,
            "kv": 243.45,
        },
    )
    table = ds.load_emps(p)
    assert isinstance(table, Table)
    assert table.names == ("qm", "qg", "vir", "pulses_N") and table.units == ("m", "m", "V", "N")
    direct = table.experiment(["vir"], ["qm"])
    closed = table.experiment(["qg"], ["vir", "qm"])
    assert direct.n_samples == closed.n_samples == n and direct.dt == pytest.approx(1e-3, rel=1e-12)
    scipy.io.savemat(p, {"t": t, "qm": np.ones((n, 1))})
    with pytest.raises(DataError, match=r"missing qg, vir"):
        ds.load_emps(p)
    scipy.io.savemat(p, {"t": t, "qm": np.ones((n, 1)), "qg": np.ones((n - 1, 1)), "vir": np.ones((n, 1))})
    with pytest.raises(DataError, match=r"variable 'qg' has 49 samples but t has 50"):
        ds.load_emps(p)


def test_load_daisy_with_root_synthetic(tmp_path):
    np.savetxt(tmp_path / "ballbeam.dat", np.arange(20.0).reshape(10, 2))
    exp = ds.load_daisy("ballbeam", root=tmp_path)
    assert (exp.n_samples, exp.n_inputs, exp.n_outputs, exp.dt) == (10, 1, 1, 0.1)
    np.savetxt(tmp_path / "robot_arm.dat", np.ones((10, 3)))
    with pytest.raises(DataError, match=r"expected 2 columns \(1 inputs, 1 outputs\); got shape \(10, 3\)"):
        ds.load_daisy("Robot_Arm", root=tmp_path)
    with pytest.raises(DataError, match=r"does not exist"):
        ds.load_daisy("CD_player_arm", root=tmp_path)


# ----------------------------------------------------------------- the real files
_DSPACE_LENGTHS = {  # 2 s records at 10 kHz; the staircases last 2, 2.75 and 4 s (Capture.Length)
    "20_hz_no_lp": 40001,
    "20_hz_lp": 40001,
    "40_hz_no_lp": 27501,
    "100_hz_no_lp": 20001,
    "tri50_1": 20001,
    "tri100_1": 20001,
    "sine50_1": 20001,
    "sine100_1": 20001,
    "prbn_1": 20001,
    "bigsine_1": 20001,
}


@pytest.mark.realdata
@needs_shared
@pytest.mark.parametrize("stem", sorted(_DSPACE_LENGTHS))
def test_real_dspace_piezo(stem):
    exp = ds.load_dspace_piezo(ds.SHARED_DATA / "piezo_dspace_preisach" / f"{stem}.mat")
    assert exp.n_samples == _DSPACE_LENGTHS[stem]
    assert exp.dt == 1e-4 and exp.t0 == 0.0
    assert (exp.n_inputs, exp.n_outputs) == (1, 1)
    # README: drive about +-90 V; the feedforward runs overshoot to about -100 V
    assert 60.0 < np.max(np.abs(exp.u)) <= 101.0
    # each file starts idle at the initial voltage for 1-1.5 s
    assert np.ptp(exp.u[: int(0.9 / exp.dt)]) < 1.0


@pytest.mark.realdata
@needs_shared
def test_real_smarthysteresis():
    exp = ds.load_smarthysteresis(ds.SHARED_DATA / "piezo_smarthysteresis" / "hysteresis_v_150_1hz.csv")
    assert exp.n_samples == 50001
    assert exp.dt == pytest.approx(2e-4, rel=1e-6)
    assert np.max(np.abs(exp.y)) == pytest.approx(19.7, abs=0.1)  # README: about +-19.7 um
    start = exp.time[np.flatnonzero(np.abs(exp.u[:, 0]) > 1.0)[0]]
    assert start == pytest.approx(3.26, abs=0.02)  # README: sine starts near t = 3.26 s


@pytest.mark.realdata
@needs_shared
@pytest.mark.parametrize("file_name, has_pulses", [("DATA_EMPS.mat", False), ("DATA_EMPS_PULSES.mat", True)])
def test_real_emps(file_name, has_pulses):
    table = ds.load_emps(ds.SHARED_DATA / "emps" / file_name)
    assert table.n_samples == 24841
    assert table.dt == pytest.approx(1e-3, rel=1e-6)
    assert ("pulses_N" in table.names) == has_pulses
    if has_pulses:
        assert set(np.unique(table.column("pulses_N"))) == {0.0, 5.0}  # 5 N force pulses
    exp = table.experiment(["vir"], ["qm"])
    assert exp.n_samples == 24841


@pytest.mark.realdata
@needs_shared
@pytest.mark.parametrize(
    "name, n, n_in, n_out, dt",
    [
        ("cd_player_arm", 2048, 2, 2, 1.0),
        ("flexible_structure", 8523, 2, 28, 1 / 1024),
        ("robot_arm", 1024, 1, 1, 1.0),
        ("ballbeam", 1000, 1, 1, 0.1),
    ],
)
def test_real_daisy(name, n, n_in, n_out, dt):
    exp = ds.load_daisy(name)
    assert (exp.n_samples, exp.n_inputs, exp.n_outputs) == (n, n_in, n_out)
    assert exp.dt == dt


@pytest.mark.realdata
@needs_shared
def test_real_files_through_the_generic_reader():
    # EMPS time stamps jitter by ~3e-5 dt: within the one sample-time rule's tolerance, refused
    # only by a caller asking for a stricter one
    path = ds.SHARED_DATA / "emps" / "DATA_EMPS.mat"
    with pytest.raises(DataError, match=r"not uniform"):
        read_table(path, time_rtol=1e-6)
    table = read_table(path)
    assert set(table.names) == {"qm", "qg", "vir"}  # the scalar gains are not columns
    # the dSPACE struct: fields flattened (the variable name dropped), X.Data the time axis;
    # the same samples and grid as the dedicated loader
    path = ds.SHARED_DATA / "piezo_dspace_preisach" / "tri50_1.mat"
    table, exp = read_table(path), ds.load_dspace_piezo(path)
    assert table.names == ("Y(1).Data", "Y(2).Data", "Y(3).Data")
    assert (table.dt, table.t0, table.n_samples) == (exp.dt, exp.t0, exp.n_samples)
    assert np.array_equal(table.column("Y(1).Data"), exp.y[:, 0])
    assert np.array_equal(table.column("Y(3).Data"), exp.u[:, 0])
