"""``--uncertainty B.csv [--uncertainty-grid FMIN:FMAX:N]`` on the identify verbs."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from _subspace_systems import band_limited, random_stage, record
from conftest import assert_one_line_error, run_main, snapshot
from stageid.data import write_csv
from stageid.frf import read_frd
from stageid.models import load_model, save_model

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(scope="module")
def record_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("uncertainty")
    g = random_stage(8, m=1, q=2, modes=2).with_names(("u",), ("y1", "y2"))
    write_csv(d / "rec.csv", record(g, band_limited(4000, 1, g.dt, 0), 0.02, 0))
    return d / "rec.csv"


@pytest.fixture(scope="module")
def frf_file(tmp_path_factory):
    from test_uncertainty_frd import noisy_frf, two_mode_plant

    d = tmp_path_factory.mktemp("uncertainty_frd")
    frd = noisy_frf(two_mode_plant(), np.linspace(1, 200, 200), 0)
    write_csv(d / "frf.csv", frd.to_columns())
    return d / "frf.csv"


def _statespace(record_file, out_dir, *extra):
    return run_main(
        "identify", "statespace", record_file, "--inputs", "u", "--outputs", "y1,y2", "--horizon", "20",
        "--order", "4", "-o", out_dir / "m.json", *extra,
    )  # fmt: skip


def test_statespace_writes_the_model_response_with_its_std(record_file, tmp_path):
    rc, _, err = _statespace(record_file, tmp_path, "--uncertainty", tmp_path / "b.csv", "--report", tmp_path / "rep")
    assert rc == 0, err
    table = read_frd(tmp_path / "b.csv")
    model = load_model(tmp_path / "m.json")
    assert table.n_freqs == 200 and table.outputs == ("y1", "y2") and table.inputs == ("u",)
    assert table.std is not None and np.all(table.std > 0)
    np.testing.assert_allclose(table.response, model.frequency_response(table.freqs), rtol=1e-9)
    assert np.all(np.diff(np.log(table.freqs)) > 0) and 0.5 < table.freqs[0] < 2 and 99 < table.freqs[-1] < 102
    assert "uncertainty/relative_std_median_percent/y1_u" in (tmp_path / "rep" / "metrics.json").read_text()
    # the grid as asked
    rc, _, err = _statespace(
        record_file, tmp_path, "--uncertainty", tmp_path / "c.npz", "--uncertainty-grid", "2:250:7"
    )
    assert rc == 0, err
    table = read_frd(tmp_path / "c.npz")
    np.testing.assert_allclose(table.freqs, np.geomspace(2, 250, 7))


@pytest.mark.parametrize(
    "grid, fragment",
    [
        ("0:100:10", "0 < FMIN < FMAX"),
        ("1:300:10", "Nyquist"),
        ("50:5:10", "0 < FMIN < FMAX"),
        ("5:5:10", "0 < FMIN < FMAX"),
        ("1:100:1", "N <= "),
        ("1:100", "FMIN:FMAX:N"),
        ("a:b:c", "FMIN:FMAX:N"),
        ("1:100:2.5", "FMIN:FMAX:N"),
        ("nan:50:3", "FMIN:FMAX:N"),
        ("1:inf:3", "FMIN:FMAX:N"),
    ],
)
def test_bad_grid_is_one_line_and_no_file(record_file, tmp_path, grid, fragment):
    before = snapshot(tmp_path)
    rc, _, err = _statespace(record_file, tmp_path, "--uncertainty", tmp_path / "b.csv", "--uncertainty-grid", grid)
    assert_one_line_error(rc, err, "--uncertainty-grid", fragment)
    assert snapshot(tmp_path) == before  # neither the table nor the model


def test_grid_without_file_and_bad_file_are_refused(record_file, frf_file, tmp_path):
    rc, _, err = _statespace(record_file, tmp_path, "--uncertainty-grid", "1:100:10")
    assert_one_line_error(rc, err, "--uncertainty-grid needs --uncertainty")
    rc, _, err = _statespace(record_file, tmp_path, "--uncertainty", tmp_path / "b.txt")
    assert_one_line_error(rc, err, "b.txt")
    rc, _, err = _statespace(record_file, tmp_path, "--uncertainty", record_file)  # an input of the command
    assert_one_line_error(rc, err, "input")
    assert not (tmp_path / "m.json").exists()


def test_frd_writes_the_fit_uncertainty(frf_file, tmp_path):
    args = ["identify", "frd", frf_file, "--order", "4", "--dt", "0.002", "-o", tmp_path / "m.json"]
    rc, out, err = run_main(*args, "--uncertainty", tmp_path / "b.csv", "--report", tmp_path / "rep")
    assert rc == 0, err
    table = read_frd(tmp_path / "b.csv")
    assert table.n_freqs == 200 and table.freqs[0] == pytest.approx(1) and table.freqs[-1] == pytest.approx(200)
    np.testing.assert_allclose(table.response, load_model(tmp_path / "m.json").frequency_response(table.freqs))
    assert np.all(table.std > 0) and "uncertainty" in out
    before = snapshot(tmp_path)
    rc, _, err = run_main(*args, "--uncertainty", tmp_path / "c.csv", "--uncertainty-grid", "1:300:20")
    assert_one_line_error(rc, err, "Nyquist")
    assert snapshot(tmp_path) == before
    # continuous fits have no Nyquist limit
    cont = ["identify", "frd", frf_file, "--order", "4", "--continuous", "-o", tmp_path / "c.json"]
    rc, _, err = run_main(*cont, "--uncertainty", tmp_path / "c.csv", "--uncertainty-grid", "1:1000:20")
    assert rc == 0, err


def test_closed_loop_grid_above_nyquist_is_refused_before_fitting(tmp_path, monkeypatch):
    import stageid.closedloop.estimator as est
    from _closedloop_plant2x2 import DT, controller, plant
    from stageid.closedloop import simulate_closed_loop
    from stageid.signals import chirp

    def no_fit(*args, **kwargs):
        raise AssertionError("a closed-loop pair was fitted before the grid was checked")

    monkeypatch.setattr(est, "select_order", no_fit)
    monkeypatch.setattr(est, "pem", no_fit)
    r = chirp(0.0, 2500.0, duration=0.2, dt=DT, amplitude=1e-6)
    paths = []
    for j in range(2):
        R = np.zeros((r.size, 2))
        R[:, j] = r
        y, _ = simulate_closed_loop(plant(), controller(), R, DT, 70.0, seed=10 + j)
        write_csv(tmp_path / f"e{j}.csv", {"r1": R[:, 0], "r2": R[:, 1], "y1": y[:, 0], "y2": y[:, 1]}, dt=DT)
        paths.append(tmp_path / f"e{j}.csv")
    save_model(controller(), tmp_path / "K.json")
    before = snapshot(tmp_path)
    rc, _, err = run_main(
        "identify", "closed-loop", *paths, "--references", "r1,r2", "--outputs", "y1,y2", "--controller",
        tmp_path / "K.json", "-o", tmp_path / "G.json", "--uncertainty", tmp_path / "b.csv",
        "--uncertainty-grid", "20:3000:50",
    )  # fmt: skip
    assert_one_line_error(rc, err, "Nyquist", "2500")
    assert snapshot(tmp_path) == before
