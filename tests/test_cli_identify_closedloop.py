"""`stageid identify closed-loop`: the issue's acceptance check on our own 2x2 plant, and the error contract."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from stageid.cli.main import main
from stageid.closedloop import simulate_closed_loop
from stageid.data import write_csv
from stageid.models import StateSpaceModel, load_model, save_model, series
from stageid.signals import chirp

sys.path.insert(0, str(Path(__file__).parent))
from _closedloop_plant2x2 import DT, UNSTABLE, controller, plant  # noqa: E402


def _experiments(tmp_path: Path, snr_db: float = 70.0, with_inputs: bool = False, ctrl=None) -> list[str]:
    r = chirp(0.0, 2500.0, duration=2.0, dt=DT, amplitude=1e-6)
    paths = []
    for j in range(2):
        R = np.zeros((r.size, 2))
        R[:, j] = r
        y, u = simulate_closed_loop(plant(), ctrl or controller(), R, DT, snr_db, seed=10 + j)
        cols = {"r1": R[:, 0], "r2": R[:, 1], "y1": y[:, 0], "y2": y[:, 1]}
        if with_inputs:
            cols.update(F1=u[:, 0], F2=u[:, 1])
        path = tmp_path / f"exp{j}.csv"
        write_csv(path, cols, dt=DT)
        paths.append(str(path))
    return paths


@pytest.mark.slow
def test_issue_check_unstable_2x2_through_cli(tmp_path: Path) -> None:
    """Unseen-style check: one chirp per axis, 70 dB SNR per output, known decentralised lead-lag."""
    exps = _experiments(tmp_path)
    save_model(controller(), tmp_path / "K.json")
    out = tmp_path / "G.json"
    rc = main(
        [
            "identify",
            "closed-loop",
            *exps,
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "K.json"),
            "-o",
            str(out),
        ]
    )
    assert rc == 0
    G = load_model(out)
    assert G.dt is None  # continuous by default
    f = np.geomspace(20.0, 300.0, 300)
    Gh, Gt = G.frequency_response(f), plant().frequency_response(f)
    for i in range(2):
        # diagonal: within 1 % of the true plant at every frequency of the band (issue's target)
        assert np.max(np.abs(Gh[:, i, i] - Gt[:, i, i]) / np.abs(Gt[:, i, i])) < 0.01
        # coupling: within 5 % of its own peak over the band (issue's target)
        k = 1 - i
        assert np.max(np.abs(Gh[:, i, k] - Gt[:, i, k])) / np.max(np.abs(Gt[:, i, k])) < 0.05
    poles = G.to_statespace(minimal=False).poles()
    rhp = np.sort(poles[poles.real > 0].real)
    assert rhp.size >= 2
    for true in UNSTABLE:  # both unstable poles within 5 %
        assert np.min(np.abs(rhp - true)) / true < 0.05


def test_controller_with_wrong_dimensions_is_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exps = _experiments(tmp_path)
    K1 = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.0]], DT)
    save_model(K1, tmp_path / "K1.json")
    out = tmp_path / "G.json"
    rc = main(
        [
            "identify",
            "closed-loop",
            *exps,
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "K1.json"),
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "controller" in err and "1 inputs" in err


def test_loop_not_closed_by_controller_is_detected_from_plant_inputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    exps = _experiments(tmp_path, with_inputs=True)
    K = controller()
    wrong = StateSpaceModel(K.A, K.B, 1.3 * K.C, 1.3 * K.D, K.dt, K.inputs, K.outputs)  # 30 % more gain
    save_model(wrong, tmp_path / "Kw.json")
    out = tmp_path / "G.json"
    rc = main(
        [
            "identify",
            "closed-loop",
            *exps,
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "Kw.json"),
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "not closed by this controller" in err


@pytest.mark.slow
def test_loop_not_closed_by_controller_is_detected_without_plant_inputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No u columns: a controller of a different design (80 Hz instead of 110 Hz crossover)
    shows as a deduced plant the [0, 2] diagonal cannot follow (measured: 15 % over the band)."""
    from stageid.models import TransferMatrix
    from stageid.plants.maglev import lead_lag

    exps = _experiments(tmp_path)
    m1, m2 = lead_lag(2.5, 45.0, 70.0, 80.0), lead_lag(2.0, 70.0, 60.0, 80.0)
    other = TransferMatrix(
        [[m1[0], [0.0]], [[0.0], m2[0]]], [[m1[1], [1.0]], [[1.0], m2[1]]], None, ("e1", "e2"), ("F1", "F2")
    )
    save_model(other.to_statespace(minimal=False).c2d(DT, "tustin"), tmp_path / "Ko.json")
    out = tmp_path / "G.json"
    rc = main(
        [
            "identify",
            "closed-loop",
            *exps,
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "Ko.json"),
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "not closed by this controller" in err


def test_right_controller_passes_the_plant_input_check(tmp_path: Path) -> None:
    from stageid.closedloop import controller_residual
    from stageid.data import read_table

    exps = _experiments(tmp_path, with_inputs=True)
    t = read_table(exps[0])
    res = controller_residual(
        controller(),
        np.column_stack([t.column("r1"), t.column("r2")]),
        np.column_stack([t.column("y1"), t.column("y2")]),
        np.column_stack([t.column("F1"), t.column("F2")]),
        DT,
    )
    assert np.all(res < 1e-6)  # the simulator closes the loop exactly with this controller


def test_singular_deduction_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A controller with a zero on the unit circle (z = 1) makes M (I - T) singular at DC."""
    exps = _experiments(tmp_path)
    K = controller()
    # a differentiator (1 - z^-1) after the controller on each channel: zeros at z = 1
    diff = StateSpaceModel(np.zeros((2, 2)), np.eye(2), -np.eye(2), np.eye(2), DT, K.outputs, K.outputs)
    Kd = series(K, diff)
    save_model(Kd, tmp_path / "Kd.json")
    out = tmp_path / "G.json"
    rc = main(
        [
            "identify",
            "closed-loop",
            *exps,
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "Kd.json"),
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "singular at 0 Hz" in err


def test_two_references_excited_in_one_file_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    r = chirp(0.0, 2500.0, duration=0.2, dt=DT, amplitude=1e-6)
    y, _ = simulate_closed_loop(plant(), controller(), np.column_stack([r, r]), DT, 70.0)
    write_csv(tmp_path / "both.csv", {"r1": r, "r2": r, "y1": y[:, 0], "y2": y[:, 1]}, dt=DT)
    save_model(controller(), tmp_path / "K.json")
    rc = main(
        [
            "identify",
            "closed-loop",
            str(tmp_path / "both.csv"),
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "K.json"),
            "-o",
            str(tmp_path / "G.json"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "one reference per experiment" in err


def test_band_above_nyquist_is_rejected_before_fitting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # before: --band 20:3000 (Nyquist 2.5 kHz) was rejected only after all closed-loop fits (~100 s)
    import stageid.closedloop.estimator as est

    def no_fit(*args, **kwargs):
        raise AssertionError("a closed-loop pair was fitted before the band was checked")

    monkeypatch.setattr(est, "select_order", no_fit)
    monkeypatch.setattr(est, "pem", no_fit)
    r = chirp(0.0, 2500.0, duration=0.2, dt=DT, amplitude=1e-6)
    paths = []
    for j in range(2):
        R = np.zeros((r.size, 2))
        R[:, j] = r
        y, _ = simulate_closed_loop(plant(), controller(), R, DT, 70.0, seed=10 + j)
        write_csv(tmp_path / f"e{j}.csv", {"r1": R[:, 0], "r2": R[:, 1], "y1": y[:, 0], "y2": y[:, 1]}, dt=DT)
        paths.append(str(tmp_path / f"e{j}.csv"))
    save_model(controller(), tmp_path / "K.json")
    out = tmp_path / "G.json"
    rc = main(
        [
            "identify",
            "closed-loop",
            *paths,
            "--references",
            "r1,r2",
            "--outputs",
            "y1,y2",
            "--controller",
            str(tmp_path / "K.json"),
            "--band",
            "20:3000",
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and not out.exists()
    assert len(err.splitlines()) == 1 and "Nyquist frequency 2500 Hz" in err and "got 20-3000 Hz" in err


@pytest.mark.slow
def test_closed_loop_output_is_the_identified_loop(tmp_path: Path) -> None:
    """--closed-loop-output writes the prediction-error closed loop r -> y at the data's sample time."""
    from stageid.models import feedback

    exps = _experiments(tmp_path)
    save_model(controller(), tmp_path / "K.json")
    args = ["identify", "closed-loop", *exps, "--references", "r1,r2", "--outputs", "y1,y2"]
    args += ["--controller", str(tmp_path / "K.json"), "-o", str(tmp_path / "G.json")]
    assert main([*args, "--closed-loop-output", str(tmp_path / "T.json")]) == 0
    T = load_model(tmp_path / "T.json")
    assert T.dt == pytest.approx(DT) and T.inputs == ("r1", "r2") and T.outputs == ("y1", "y2")
    truth = feedback(plant().to_statespace(minimal=False).c2d(DT, "zoh"), controller())
    f = np.geomspace(5.0, 1000.0, 200)
    t_true = truth.frequency_response(f)[:, :2, :2]  # references to the measured outputs
    assert np.abs(T.frequency_response(f) - t_true).max() < 0.01 * np.abs(t_true).max()  # 70 dB records
