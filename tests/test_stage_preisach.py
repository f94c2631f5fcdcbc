"""Preisach hysteresis inside the stage model: object, JSON, identification, exact inverse, CLI, bad input."""

import json

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter

from stageid import ModelError, ModelFormatError
from stageid.cli.main import main
from stageid.data import Experiment
from stageid.data.io import read_table, write_csv
from stageid.hysteresis import CreepTerm, PIModel
from stageid.hysteresis.models.preisach import PreisachModel
from stageid.hysteresis.stage import StageModel
from stageid.hysteresis.stage.dynamics import transfer_to_statespace
from stageid.hysteresis.stage.identification import StageIdentifier
from stageid.hysteresis.stage.inverse import clipped_count, preisach_creep_feedforward, stage_feedforward
from stageid.models import load_model
from stageid.models.serialization import dumps, loads
from stageid.signals import decaying_triangle, triangle

DT = 1e-4
LEVELS = 8


def _weights(n=LEVELS):
    # smooth, asymmetric, non-negative density (not a PI model)
    i, j = np.tril_indices(n)
    return np.exp(-(((i - j) / (0.4 * n)) ** 2)) * (1.0 + 0.5 * i / n) / n


def _hyst(n=LEVELS, offset=0.3):
    return PreisachModel((-10.0, 10.0), _weights(n), offset, input_limits=(-10.0, 10.0))


def _resonance(f_n=800.0, zeta=0.05):
    wn = 2 * np.pi * f_n
    b, a, _ = cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), DT, "zoh")
    b = np.ravel(b) * np.sum(a) / np.sum(np.ravel(b))
    return b, a


def _stage(creep=True):
    b, a = _resonance()
    c = CreepTerm(time_constants=[0.01, 0.1], weights=[0.02, 0.01], sample_time=DT) if creep else None
    return StageModel(_hyst(), transfer_to_statespace(b, a, DT), c)


def test_simulate_is_preisach_plus_creep_then_dynamics():
    s = _stage()
    u = decaying_triangle(50.0, 4, DT, amplitude=9.0)
    v = s.hysteresis.simulate(u)[:, 0] + s.creep.run(u)[0]
    b, a = _resonance()
    expect = v[0] + lfilter(b, a, v - v[0])
    np.testing.assert_allclose(s.simulate(u, DT)[:, 0], expect, rtol=0, atol=1e-12)
    assert s.dt == DT and s.creep_term is s.creep


def test_json_round_trip_is_byte_stable():
    s = _stage()
    text = dumps(s.to_dict())
    back = loads(text)
    assert isinstance(back, StageModel) and isinstance(back.hysteresis, PreisachModel)
    assert dumps(back.to_dict()) == text
    assert json.loads(text)["creep"]["time_constants"] == [0.01, 0.1]
    u = decaying_triangle(50.0, 3, DT, amplitude=8.0)
    np.testing.assert_array_equal(back.simulate(u, DT), s.simulate(u, DT))
    # a PI stage file keeps its old form (no `creep` key at the stage level)
    assert "creep" not in StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])).to_dict()


def test_stage_creep_is_for_preisach_only_and_bad_fields_are_named():
    c = CreepTerm(time_constants=[0.01], weights=[0.02], sample_time=DT)
    with pytest.raises(ModelError, match="carries its own creep"):
        StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), None, c)
    d = _stage().to_dict()
    d["creep"]["weights"] = [-1.0, 0.0]
    with pytest.raises(ModelFormatError, match="creep"):
        StageModel.from_dict(d)
    d = _stage().to_dict()
    d["creep"]["sample_time"] = 2 * DT
    with pytest.raises(ModelFormatError, match="differs from the creep"):
        StageModel.from_dict(d)


@pytest.mark.parametrize("state", [None, [-2.0, 1.0]])
def test_preisach_creep_inverse_is_exact(state):
    h = _hyst()
    c = CreepTerm(time_constants=[0.005, 0.05], weights=[0.03, 0.02], sample_time=DT, state=state)
    s = StageModel(h.with_state(h.consistent_state(0.0)), None, c)
    t = np.arange(4000) * DT
    ref = 2.0 + 1.2 * np.sin(2 * np.pi * 7 * t) * np.exp(-2 * t)
    u = preisach_creep_feedforward(s.hysteresis, c, ref, DT)
    y = s.simulate(u, DT)[:, 0]
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-11)
    # the creep is folded in: inverting the hysteresis alone misses by the creep's share
    u0 = preisach_creep_feedforward(s.hysteresis, None, ref, DT)
    assert np.max(np.abs(s.simulate(u0, DT)[:, 0] - ref)) > 0.05


def test_stage_inverse_tracks_a_scan_on_the_exact_model():
    s = _stage()
    ref = 2.0 + 1.0 * triangle(100.0, 0.05, DT)
    ref = np.r_[np.full(200, ref[0]), ref, np.full(200, ref[-1])]
    u = stage_feedforward(s, ref, DT)
    e = s.simulate(u, DT)[:, 0] - ref
    assert np.max(np.abs(e)) < 1e-3 * np.ptp(ref)


def test_auto_regularisation_removes_the_clipping_of_a_badly_inverted_zero():
    # an identified-like G with a sampled zero just outside -1: exact inversion near Nyquist
    # asks for drives far beyond the limits on every corner of a scan
    b, a = np.array([0.00733, 0.17470, 0.17915]), np.array([1.0, -1.58130, 0.94248])
    b = b * np.sum(a) / np.sum(b)
    h = PreisachModel((-10.0, 10.0), _weights(), 0.0, input_limits=(-10.0, 10.0))
    s = StageModel(h, transfer_to_statespace(b, a, DT))
    lo_y, hi_y = h.simulate(np.r_[-10.0])[0, 0], h.simulate(np.r_[10.0])[0, 0]
    ref = 0.5 * (lo_y + hi_y) + 0.4 * (hi_y - lo_y) * triangle(100.0, 0.05, DT)
    exact = stage_feedforward(s, ref, DT, regularisation=1e-8)[:, 0]
    auto = stage_feedforward(s, ref, DT)[:, 0]
    plain = stage_feedforward(StageModel(h), ref, DT)[:, 0]
    assert clipped_count(exact, -10.0, 10.0) > clipped_count(plain, -10.0, 10.0) + 5
    assert clipped_count(auto, -10.0, 10.0) <= clipped_count(plain, -10.0, 10.0)
    # and the auto drive still inverts the dynamics: the model follows the scan
    e = s.simulate(auto[:, None], DT)[:, 0] - ref
    assert np.max(np.abs(e[200:])) < 0.02 * np.ptp(ref)


def _records(seed=0, noise=1e-4):
    s = _stage()
    rng = np.random.default_rng(seed)
    out = []
    for f, cycles in ((20.0, 6), (100.0, 20)):
        u = decaying_triangle(f, cycles, DT, amplitude=10.0)
        h = s.hysteresis.with_state(s.hysteresis.consistent_state(u[0]))
        y = s.with_hysteresis(h).simulate(u, DT)[:, 0] + noise * rng.standard_normal(u.size)
        out.append(Experiment(u[:, None], y[:, None], DT, ("V",), ("y",)))
    return s, out


def test_identification_recovers_a_preisach_stage():
    true, recs = _records()
    fit = StageIdentifier("preisach", n_levels=LEVELS, dynamics=2, creep=(0.01, 0.1), smoothing=0.0).fit(recs)
    assert isinstance(fit.model.hysteresis, PreisachModel) and fit.dynamics_order == 2
    assert max(fit.max_error_percent) < 0.03  # noise: 1e-4 of a 3.4 range, max ~0.012 %
    f_fit = np.sort(np.abs(np.log(fit.model.dynamics.poles().astype(complex))))
    f_true = np.sort(np.abs(np.log(true.dynamics.poles().astype(complex))))
    np.testing.assert_allclose(f_fit, f_true, rtol=2e-3)
    np.testing.assert_allclose(fit.model.creep.weights, true.creep.weights, atol=2e-3)
    # without dynamics the same records are fitted far worse: the fit is not the hysteresis alone
    ri = StageIdentifier("preisach", n_levels=LEVELS, dynamics=None, creep=(0.01, 0.1), smoothing=0.0).fit(recs)
    assert max(ri.max_error_percent) > 5 * max(fit.max_error_percent)


def _write(tmp_path, recs):
    paths = []
    for k, e in enumerate(recs):
        p = tmp_path / f"r{k}.csv"
        write_csv(p, {"t": np.arange(e.n_samples) * DT, "V": e.u[:, 0], "y": e.y[:, 0]})
        paths.append(str(p))
    return paths


def test_cli_identify_simulate_compensate_a_preisach_stage(tmp_path, capsys):
    _, recs = _records()
    paths = _write(tmp_path, recs)
    out = tmp_path / "s.json"
    args = ["identify", "hysteresis", *paths, "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, "--levels", str(LEVELS), "--dynamics", "2", "--creep", "0.01,0.1", "-o", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["kind"] == "stage" and d["hysteresis"]["kind"] == "preisach" and d["creep"] is not None
    model = load_model(str(out))
    direct = StageIdentifier("preisach", n_levels=LEVELS, dynamics=2, creep=(0.01, 0.1)).fit(recs).model
    np.testing.assert_array_equal(model.hysteresis.weights, direct.hysteresis.weights)  # the CLI is the estimator
    # simulate runs the file; compensate inverts it offline
    assert main(["simulate", str(out), paths[0], "-o", str(tmp_path / "y.csv")]) in (0, None)
    y = read_table(tmp_path / "y.csv").column("y")
    np.testing.assert_allclose(y, model.simulate(recs[0].u, DT)[:, 0], atol=1e-9)
    ref = model.output_offset + 1.0 + 0.8 * triangle(50.0, 0.06, DT)
    ref = np.r_[np.full(300, ref[0]), ref, np.full(300, ref[-1])]
    write_csv(tmp_path / "ref.csv", {"t": np.arange(ref.size) * DT, "yref": ref})
    drive = tmp_path / "u.csv"
    assert main(["compensate", str(out), str(tmp_path / "ref.csv"), "--column", "yref", "-o", str(drive)]) == 0
    u = read_table(drive).column("V")
    e = model.simulate(u, DT)[:, 0] - ref
    assert np.max(np.abs(e)) < 1e-3 * np.ptp(ref)


def test_cli_rate_independent_preisach_is_unchanged(tmp_path):
    from stageid.hysteresis import PreisachIdentifier

    _, recs = _records()
    paths = _write(tmp_path, recs)
    out = tmp_path / "p.json"
    args = ["identify", "hysteresis", *paths, "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, "--levels", str(LEVELS), "--creep", "none", "--quiet", "-o", str(out)]) == 0
    m = load_model(str(out))
    assert isinstance(m, PreisachModel)
    np.testing.assert_array_equal(m.weights, PreisachIdentifier(n_levels=LEVELS).fit(recs).model.weights)


@pytest.mark.parametrize(
    "extra, cause, constant",
    [
        # a grid finer than the records is filled by the smoothness prior; only an input that
        # never moves (no cell determined) is refused
        (["--levels", "60", "--dynamics", "1", "--creep", "0.01"], "constant input", True),
        (["--levels", str(LEVELS), "--dynamics", "40"], "an order these records support", False),
    ],
)
def test_cli_bad_preisach_stage_input_is_one_line_exit_2_no_file(tmp_path, capsys, extra, cause, constant):
    _, recs = _records()
    short = [Experiment(e.u[:1500] * (0 if constant else 1), e.y[:1500], DT, ("V",), ("y",)) for e in recs]
    paths = _write(tmp_path, short)
    out = tmp_path / "s.json"
    args = ["identify", "hysteresis", *paths, "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, *extra, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert cause in err and "\n" not in err
    assert not out.exists()


def test_cli_preisach_creep_without_a_time_axis_is_refused(tmp_path, capsys):
    _, recs = _records()
    p = tmp_path / "r.csv"
    write_csv(p, {"V": recs[0].u[:, 0], "y": recs[0].y[:, 0]})
    out = tmp_path / "s.json"
    args = ["identify", "hysteresis", str(p), "--input", "V", "--output", "y", "--model", "preisach"]
    assert main([*args, "--levels", str(LEVELS), "--creep", "0.01", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and not out.exists()


def test_c_export_of_a_preisach_stage_is_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / "s.json"
    path.write_text(dumps(_stage().to_dict()))
    code = main(["export", "c", str(path), "--prefix", "st", "-o", str(tmp_path / "out")])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "Preisach hysteresis has no C export" in err and "\n" not in err
    assert not (tmp_path / "out").exists()


def test_stage_json_without_creep_key_still_loads():
    d = _stage(creep=False).to_dict()
    assert "creep" not in d
    s = StageModel.from_dict(d)
    assert s.creep is None and isinstance(s.hysteresis, PreisachModel)
    with pytest.raises(ModelFormatError, match="optionally `creep`"):
        StageModel.from_dict({**d, "extra": 1})


@pytest.mark.study
@pytest.mark.slow
@pytest.mark.realdata
def test_measured_forc_records_preisach_stage():
    """Preisach stage on the dSPACE 20 + 100 Hz FORC records (RESULTS.md section 4d): the 40 Hz
    record within the issue's 1.5 % max; the 100 Hz record no longer stuck in a lead-lag (its RMS
    was 0.69 % before the lag-and-delay starts, 0.23 % with them)."""
    from _dspace_records import dspace_record

    def record(name):
        return dspace_record(name)[:2]

    train = [record("20_hz_no_lp"), record("100_hz_no_lp")]
    fit = StageIdentifier("preisach", dynamics=1, creep=(0.01, 0.1, 1.0), sample_time=1e-4).fit(train)
    assert fit.rms_error_percent[1] < 0.4
    u, y = record("40_hz_no_lp")
    m = fit.model
    e = y - m.with_hysteresis(m.hysteresis.with_state(m.hysteresis.consistent_state(u[0], "zero"))).simulate(u)[:, 0]
    assert 100 * np.max(np.abs(e - e.mean())) / np.ptp(y) <= 1.5  # measured 0.61 %
