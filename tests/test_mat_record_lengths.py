"""MAT files whose vectors are not all of one length: parameters beside the record, and records that
cannot be aligned.

Synthetic files are written with scipy.io.savemat so these run everywhere; the magnetic levitation
record (signals beside rows of sensor means) is read in place and skips when absent.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io

from conftest import run_main
from stageid import DataError, StageIdWarning
from stageid.data import datasets as ds
from stageid.data import read_table
from stageid.models import StateSpaceModel, save_model

DT = 1e-3
N = 300


def _gain_model(path, inputs, outputs=("z",)):
    """A static model: every output is twice the first input."""
    k = len(inputs)
    D = np.zeros((len(outputs), k))
    D[:, 0] = 2.0
    ss = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, k)), np.zeros((len(outputs), 0)), D, dt=DT)
    save_model(ss.with_names(inputs=tuple(inputs), outputs=tuple(outputs)), path)
    return path


def _signals(seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((N, 2)), rng.standard_normal((N, 1))


def test_row_of_means_beside_the_signals_is_skipped_with_a_warning(tmp_path):
    u, y = _signals()
    path = tmp_path / "rec.mat"
    scipy.io.savemat(path, {"u": u, "y": y, "means": np.array([[0.1, 0.2, 0.3]]), "gain": 4.0})
    with pytest.warns(StageIdWarning, match=r"skipped means \(3 samples\).*300 samples"):
        table = read_table(path, ts=DT)
    assert table.names == ("u_1", "u_2", "y") and table.n_samples == N
    assert np.array_equal(table.column("u_2"), u[:, 1])


def test_the_cli_reads_such_a_file_and_says_what_it_skipped(tmp_path):
    u, y = _signals(1)
    path = tmp_path / "rec.mat"
    scipy.io.savemat(path, {"t": DT * np.arange(N)[:, None], "u": u, "y": y, "coefficients": np.ones((1, 5))})
    model = _gain_model(tmp_path / "g.json", ["u_1", "u_2"])
    code, out, err = run_main("simulate", model, path, "-o", tmp_path / "z.csv")
    assert code == 0, err
    assert np.allclose(read_table(tmp_path / "z.csv").column("z"), 2.0 * u[:, 0])
    (line,) = [s for s in err.splitlines() if "skipped" in s]
    assert "'rec.mat'" in line and "coefficients (5 samples)" in line and "300 samples" in line
    gain = _gain_model(tmp_path / "v.json", ["u_1"], ["y"])
    for initial in ("model", "estimate"):  # a static gain has no initial state to estimate
        code, out, err = run_main("validate", gain, path, "--inputs", "u_1", "--initial", initial)
        assert code == 0, err
        assert "coefficients (5 samples)" in err and "y: fit" in out


def test_signals_that_cannot_be_aligned_are_refused_in_one_line_naming_them(tmp_path):
    u, y = _signals(2)
    path = tmp_path / "cut.mat"
    # the output lost its last ten samples: which samples pair up is not the reader's guess
    scipy.io.savemat(path, {"u": u, "y": y[:-10], "means": np.zeros((1, 3))})
    with pytest.raises(DataError, match=r"unequal lengths \(300 samples: u_1, u_2; 290 samples: y; 3 samples: means\)"):
        read_table(path, ts=DT)
    model = _gain_model(tmp_path / "g.json", ["u_1", "u_2"])
    code, out, err = run_main("simulate", model, path, "--ts", str(DT), "-o", tmp_path / "z.csv")
    assert code == 2 and out == "" and not (tmp_path / "z.csv").exists()
    line = err.strip()
    assert "\n" not in line and "'cut.mat'" in line and "290 samples: y" in line and "300 samples: u_1" in line


def test_a_time_vector_sets_the_record_length(tmp_path):
    # two signals of 20 samples beside one of 300: the time axis says which is the record
    u, y = _signals(3)
    path = tmp_path / "timed.mat"
    scipy.io.savemat(path, {"t": DT * np.arange(N), "y": y, "a": np.ones((20, 1)), "b": np.ones((20, 1))})
    with pytest.warns(StageIdWarning, match=r"skipped a, b \(20 samples\)"):
        table = read_table(path)
    assert table.names == ("y",) and table.dt == pytest.approx(DT)
    # a time vector shorter than its signals is no axis for them
    scipy.io.savemat(path, {"t": DT * np.arange(100), "y": y})
    with pytest.raises(DataError, match=r"unequal lengths \(100 samples: time; 300 samples: y\)"):
        read_table(path)


MAGLEV = None if ds.SHARED_DATA is None else ds.SHARED_DATA / "maglev_closedloop" / "PD_data_with_input.mat"


@pytest.mark.realdata
@pytest.mark.skipif(MAGLEV is None or not MAGLEV.exists(), reason="../shared/data/maglev_closedloop not found")
def test_maglev_record_through_the_identification_commands(tmp_path):
    """Magnetometer signals (18343 x 3) beside rows of their means (1 x 3): the signals are read."""
    ts = str(1 / 2700)  # the record has no time vector; the README gives about 2700 Hz
    outs = "rawMeasurements_mean_subtracted1_1,rawMeasurements_mean_subtracted1_2"
    common = ["--ts", ts, "--outputs", outs]
    code, out, err = run_main(
        "identify", "statespace", MAGLEV, "--inputs", "u_1,u_2", *common, "--order", "4", "--horizon", "10",
        "-o", tmp_path / "ss.json",
    )  # fmt: skip
    assert code == 0, err
    assert "skipped receivedMeans1, receivedMeans2, receivedMeans3 (3 samples)" in err and "18343 samples" in err
    code, out, err = run_main(
        "identify", "closed-loop", MAGLEV, "--controller", "unknown", "--method", "direct",
        "--plant-inputs", "u_1,u_2", *common, "--order", "4", "-o", tmp_path / "cl.json",
    )  # fmt: skip
    assert code == 0, err
    assert json.loads((tmp_path / "cl.json").read_text())["inputs"] == ["u_1", "u_2"]
    code, out, err = run_main("validate", tmp_path / "ss.json", MAGLEV, "--ts", ts)
    assert code == 0, err
    assert "receivedMeans1" in err and "rawMeasurements_mean_subtracted1_1: fit" in out
