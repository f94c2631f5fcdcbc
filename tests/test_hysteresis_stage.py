"""Stage model (hysteresis -> creep -> unit-DC-gain dynamics): object, JSON, joint identification, inverse, CLI."""

import json

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter

from stageid import ModelError, ModelFormatError, ParameterError
from stageid.cli.main import main
from stageid.data import Experiment
from stageid.data.io import read_table, write_csv
from stageid.hysteresis import CreepTerm, ModifiedPIModel, PIIdentifier, PIModel
from stageid.hysteresis.stage import StageModel
from stageid.hysteresis.stage.dynamics import fit_unit_gain_dynamics, transfer_to_statespace
from stageid.hysteresis.stage.identification import StageIdentifier
from stageid.hysteresis.stage.inverse import stage_feedforward
from stageid.models import StateSpaceModel, load_model
from stageid.models.serialization import dumps, loads
from stageid.signals import decaying_triangle, triangle

DT = 1e-4
HYST = PIModel(r=[0.0, 2.5, 5.0, 7.5], weights=[1.0, 0.4, 0.2, 0.1])


def _resonance(f_n=800.0, zeta=0.05, dt=DT):
    wn = 2 * np.pi * f_n
    b, a, _ = cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), dt, "zoh")
    b = np.ravel(b) * np.sum(a) / np.sum(np.ravel(b))
    return b, a


def _stage(hyst=HYST):
    b, a = _resonance()
    return StageModel(hyst, transfer_to_statespace(b, a, DT))


def test_simulate_is_hysteresis_then_dynamics_at_rest():
    # analytic: a first-order lag 0.5/(1 - 0.5 z^-1) after the PI output, at rest at v[0]
    g = StateSpaceModel([[0.5]], [[1.0]], [[0.5]], [[0.0]], dt=DT)
    s = StageModel(HYST, g)
    u = np.r_[1.0, 4.0, 4.0, -2.0, 3.0]
    v = HYST.simulate(u)[:, 0]
    y = s.simulate(u, DT)[:, 0]
    # y(k) = 0.5 x(k), x(k+1) = 0.5 x(k) + v(k), at rest: x(0) = v0 / (1 - 0.5)
    expect = np.empty_like(v)
    x = 2 * v[0]
    for k in range(v.size):
        expect[k] = 0.5 * x
        x = 0.5 * x + v[k]
    np.testing.assert_allclose(y, expect, rtol=0, atol=1e-12)  # float rounding only


def test_without_dynamics_the_stage_is_its_hysteresis():
    u = decaying_triangle(20.0, 4, DT, amplitude=9.0)
    np.testing.assert_array_equal(StageModel(HYST).simulate(u), HYST.simulate(u))


def test_slow_input_reaches_the_hysteresis_output():
    # unit DC gain: after a step the stage settles on the hysteresis model's value
    u = np.r_[np.zeros(10), np.full(4000, 6.0)]
    s = _stage()
    assert s.simulate(u, DT)[-1, 0] == pytest.approx(HYST.simulate(u)[-1, 0], abs=1e-9)


def test_json_round_trip_is_byte_stable_and_composes_with_models():
    creep = CreepTerm(time_constants=[0.05], weights=[0.01], sample_time=DT)
    s = _stage(
        ModifiedPIModel(r=[0.0, 1.0], rc=[0.0, 0.8], ra=[0.0, 1.2], rb=[0.0, 0.9], weights=[1.0, 0.3], creep=creep)
    )
    text = dumps(s.to_dict())
    back = loads(text)
    assert isinstance(back, StageModel) and dumps(back.to_dict()) == text
    u = decaying_triangle(50.0, 3, DT, amplitude=2.0)
    np.testing.assert_array_equal(back.simulate(u, DT), s.simulate(u, DT))
    # the dynamics are a plain StateSpaceModel: poles of the 800 Hz resonance
    f = np.abs(np.log(s.dynamics.poles().astype(complex))) / (2 * np.pi * DT)
    np.testing.assert_allclose(f, 800.0, rtol=2e-3)  # zoh-sampled |s| = wn, not the damped freq


@pytest.mark.parametrize(
    "dyn, words",
    [
        (StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=DT), "DC gain 1"),
        (StateSpaceModel([[1.5]], [[1.0]], [[-0.5]], [[0.0]], dt=DT), "stable"),
        (StateSpaceModel([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), "discrete"),
    ],
)
def test_bad_dynamics_are_refused(dyn, words):
    with pytest.raises(ModelError, match=words):
        StageModel(HYST, dyn)


def test_malformed_stage_file_names_the_field():
    d = _stage().to_dict()
    d["dynamics"] = {"kind": "transfer"}
    with pytest.raises(ModelFormatError, match="dynamics"):
        loads(json.dumps(d))


def test_unit_gain_dynamics_fit_recovers_a_resonance():
    b, a = _resonance()
    rng = np.random.default_rng(3)
    v = np.cumsum(rng.standard_normal(6000))
    y = v[0] + lfilter(b, a, v - v[0])
    bh, ah = fit_unit_gain_dynamics([(v, y)], 2)
    np.testing.assert_allclose(np.roots(ah), np.roots(a), rtol=1e-6)  # noise-free: exact up to rounding
    assert np.sum(bh) == pytest.approx(np.sum(ah), rel=1e-12)


def test_joint_identification_recovers_a_known_stage_and_validates_at_another_rate():
    true = _stage()
    rng = np.random.default_rng(0)
    train = []
    for freq, cycles in ((20.0, 6), (100.0, 20)):
        u = decaying_triangle(freq, cycles, DT, amplitude=10.0)
        y = true.simulate(u, DT)[:, 0] + 1e-4 * rng.standard_normal(u.size)
        train.append(Experiment(u[:, None], y[:, None], DT, ("V",), ("y",)))
    fit = StageIdentifier("pi", n_operators=4, dynamics=2, creep=None).fit(train)
    assert fit.dynamics_order == 2
    f = np.abs(np.log(fit.model.dynamics.poles().astype(complex))) / (2 * np.pi * DT)
    np.testing.assert_allclose(f, 800.0, rtol=0.01)  # 1e-4 noise on a 20-unit range: pole within 1 %
    u = decaying_triangle(150.0, 20, DT, amplitude=9.0)
    e = true.simulate(u, DT)[:, 0] - fit.model.simulate(u, DT)[:, 0]
    assert 100 * np.abs(e).max() / np.ptp(true.simulate(u, DT)) < 0.5
    # the same records without dynamics leave the resonance's ringing: far worse
    flat = StageIdentifier("pi", n_operators=4, dynamics=None, creep=None).fit(train)
    assert max(flat.max_error_percent) > 5 * max(fit.max_error_percent)


def test_auto_prefers_no_dynamics_on_a_rate_independent_actuator():
    u = decaying_triangle(20.0, 8, DT, amplitude=10.0)
    y = HYST.simulate(u)[:, 0] + 1e-4 * np.random.default_rng(1).standard_normal(u.size)
    fit = StageIdentifier("pi", n_operators=4, dynamics="auto", creep=None, sample_time=DT).fit((u, y))
    assert fit.dynamics_order <= 1  # order 1 may win by a hair on noise; never the resonant orders
    assert len(fit.held_out) == 5


def test_too_high_an_order_is_a_parameter_error():
    u = decaying_triangle(20.0, 2, DT, amplitude=10.0)[:500]
    with pytest.raises(ParameterError, match="dynamics"):
        StageIdentifier("pi", n_operators=4, dynamics=20, creep=None, sample_time=DT).fit((u, HYST.simulate(u)))


def test_stage_inverse_tracks_a_fast_triangle_where_the_rate_independent_inverse_cannot():
    from stageid.hysteresis import compensate

    true = _stage()
    ref = 5.0 + 4.0 * triangle(100.0, 4, DT)
    ref = np.r_[np.full(100, ref[0]), ref]
    first = 100 + int(1 / 100.0 / DT)
    u_stage = stage_feedforward(true, ref, DT, limits=(-20.0, 20.0))
    u_flat = compensate(true.hysteresis, ref, limits=(-20.0, 20.0))
    err_stage = np.abs(true.simulate(u_stage, DT)[:, 0] - ref)[first:].max() / 8.0
    err_flat = np.abs(true.simulate(u_flat, DT)[:, 0] - ref)[first:].max() / 8.0
    assert err_stage < 0.01  # exact model: the remaining error is the inversion's regularisation
    assert err_flat > 5 * err_stage


def _write(path, u, y):
    write_csv(path, {"V": u, "y": y}, dt=DT)


def test_cli_identify_simulate_compensate_a_stage(tmp_path):
    true = _stage()
    u = decaying_triangle(50.0, 10, DT, amplitude=10.0)
    _write(tmp_path / "a.csv", u, true.simulate(u, DT)[:, 0])
    out = tmp_path / "s.json"
    args = ["identify", "hysteresis", str(tmp_path / "a.csv"), "--input", "V", "--output", "y"]
    assert (
        main(
            [
                *args,
                "--model",
                "pi",
                "--operators",
                "4",
                "--dynamics",
                "2",
                "--creep",
                "none",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    model = load_model(out)
    assert isinstance(model, StageModel) and model.dynamics_order == 2
    assert main(["simulate", str(out), str(tmp_path / "a.csv"), "-o", str(tmp_path / "sim.csv")]) == 0
    sim = read_table(tmp_path / "sim.csv").column("y")
    np.testing.assert_allclose(sim, model.simulate(u, DT)[:, 0], atol=1e-12)
    ref = 5.0 + 4.0 * triangle(100.0, 3, DT)
    write_csv(tmp_path / "ref.csv", {"yref": ref}, dt=DT)
    assert (
        main(["compensate", str(out), str(tmp_path / "ref.csv"), "--column", "yref", "-o", str(tmp_path / "d.csv")])
        == 0
    )
    drive = read_table(tmp_path / "d.csv").column("V")
    np.testing.assert_allclose(drive, stage_feedforward(model, ref, DT)[:, 0], atol=1e-12)


def test_cli_without_new_flags_is_todays_pi_identification(tmp_path):
    u = decaying_triangle(20.0, 6, DT, amplitude=10.0)
    _write(tmp_path / "a.csv", u, HYST.simulate(u)[:, 0])
    out = tmp_path / "p.json"
    assert (
        main(
            [
                "identify",
                "hysteresis",
                str(tmp_path / "a.csv"),
                "--input",
                "V",
                "--output",
                "y",
                "--model",
                "pi",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    exp = Experiment(u[:, None], read_table(tmp_path / "a.csv").column("y")[:, None], DT, ("V",), ("y",))
    assert out.read_text() == dumps(PIIdentifier("pi").fit(exp).model.to_dict())


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--dynamics", "-1"], "--dynamics"),
        (["--dynamics", "two"], "--dynamics"),
        (["--dynamics", "400"], "order these records support"),
        (["--creep", "fast"], "--creep"),
    ],
)
def test_cli_bad_stage_settings_exit_2_one_line_nothing_written(tmp_path, capsys, extra, words):
    u = decaying_triangle(20.0, 2, DT, amplitude=10.0)[:2000]
    _write(tmp_path / "a.csv", u, HYST.simulate(u)[:, 0])
    out = tmp_path / "s.json"
    code = main(
        [
            "identify",
            "hysteresis",
            str(tmp_path / "a.csv"),
            "--input",
            "V",
            "--output",
            "y",
            "--model",
            "pi",
            *extra,
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and words in err[0]
    assert not out.exists()


def test_cli_creep_without_a_time_axis_exit_2(tmp_path, capsys):
    u = decaying_triangle(20.0, 2, DT, amplitude=10.0)
    (tmp_path / "a.csv").write_text("V,y\n" + "\n".join(f"{a},{b}" for a, b in zip(u, HYST.simulate(u)[:, 0])))
    out = tmp_path / "s.json"
    code = main(
        [
            "identify",
            "hysteresis",
            str(tmp_path / "a.csv"),
            "--input",
            "V",
            "--output",
            "y",
            "--creep",
            "auto",
            "--dynamics",
            "auto",
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "time column" in err[0]
    assert not out.exists()


def test_cli_stage_at_another_sample_time_exit_2_nothing_written(tmp_path, capsys):
    path = tmp_path / "s.json"
    path.write_text(dumps(_stage().to_dict()))
    u = decaying_triangle(50.0, 2, 2 * DT, amplitude=5.0)
    write_csv(tmp_path / "u.csv", {"V": u, "yref": u}, dt=2 * DT)
    for args in (
        ["simulate", str(path), str(tmp_path / "u.csv"), "-o", str(tmp_path / "out.csv")],
        ["compensate", str(path), str(tmp_path / "u.csv"), "--column", "yref", "-o", str(tmp_path / "out.csv")],
    ):
        code = main(args)
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and "sample time" in err[0], err
        assert not (tmp_path / "out.csv").exists()


def test_auto_with_two_records_scores_every_candidate_by_leaving_one_out():
    true = _stage()
    train = []
    for freq, cycles in ((20.0, 6), (100.0, 20)):
        u = decaying_triangle(freq, cycles, DT, amplitude=10.0)
        train.append(Experiment(u[:, None], true.simulate(u, DT), DT, ("V",), ("y",)))
    fit = StageIdentifier("pi", n_operators=4, dynamics="auto", creep=None).fit(train)
    scores = {order: score for order, _, score in fit.held_out}
    assert set(scores) == {0, 1, 2, 3, 4}
    # noise-free true order 2: held-out error far below the rate-independent model's
    assert scores[2] < 0.01 * scores[0]
    assert fit.dynamics_order >= 2
