"""Lightly damped modes taken from the disturbance of the identification records.

The simulated stage: a Preisach actuator, then a resonance; a white disturbance enters before
the resonance (amplifier noise), white sensor noise after it.  The drives are slow decaying
sines, so the only evidence of a 1.5 kHz mode is the ring of the disturbance.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter

from stageid import ModelError, ModelFormatError
from stageid.cli.main import main
from stageid.data.io import write_csv
from stageid.hysteresis.models.preisach import PreisachModel
from stageid.hysteresis.stage import StageModel
from stageid.hysteresis.stage.disturbance_modes import DisturbanceMode, disturbance_modes, resonance_filter
from stageid.hysteresis.stage.dynamics import transfer_to_statespace
from stageid.hysteresis.stage.identification import StageIdentifier

DT = 1e-4


def _hysteresis():
    i, j = np.tril_indices(8)
    w = np.exp(-(((i - j) / 3.2) ** 2)) * (1.0 + 0.5 * i / 8) / 8
    return PreisachModel((-10.0, 10.0), w, 0.3, input_limits=(-10.0, 10.0))


def _resonance(f_n, zeta):
    wn = 2 * np.pi * f_n
    b, a, _ = cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), DT, "zoh")
    b = np.ravel(b) * np.sum(a) / np.sum(np.ravel(b))
    return b, a


def _drive(f, seconds):
    t = np.arange(int(round(seconds / DT))) * DT
    return 10.0 * np.exp(-1.5 * t / seconds) * np.sin(2 * np.pi * f * t)


def _records(b, a, rates, disturbance=2e-3, noise=2e-4, seed=0):
    """``(u, y)`` per rate: ``y = G[v + d] + n`` with ``v`` the Preisach output."""
    rng = np.random.default_rng(seed)
    h = _hysteresis()
    out = []
    for f, seconds in rates:
        u = _drive(f, seconds)
        v = h.with_state(h.consistent_state(u[0])).simulate(u)[:, 0]
        x = v + disturbance * rng.standard_normal(u.size)
        out.append((u, v[0] + lfilter(b, a, x - v[0]) + noise * rng.standard_normal(u.size)))
    return out


def _light_poles_hz(model, zeta_max=0.1):
    """Natural frequencies [Hz] of the model's dynamics poles with damping below ``zeta_max``."""
    if model.dynamics is None:
        return np.zeros(0)
    s = [np.log(complex(z)) / DT for z in model.dynamics.poles() if abs(z) > 0]
    return np.array([abs(x) / (2 * np.pi) for x in s if -x.real / abs(x) < zeta_max])


SLOW = ((10.0, 1.5), (20.0, 1.5))


@pytest.mark.study
def test_a_mode_rung_only_by_the_disturbance_is_recovered():
    """1.5 kHz, damping 0.02, drives at 10 and 20 Hz: without the new step the fit has no pole
    near the mode (the drives do not excite it); with it, on the spectral evidence alone
    (``"spectrum"``), the mode is within 2 % in frequency and a factor 1.5 in damping (measured
    1499 Hz, 0.0211).  The default (``"auto"``) leaves it out and says so: the drives carry
    nothing at 1.5 kHz and an autoregressive noise model holds the ring without the mode, so
    held out it does not lower the one-step prediction error."""
    b, a = _resonance(1500.0, 0.02)
    recs = _records(b, a, SLOW)
    est = StageIdentifier("preisach", n_levels=8, dynamics=2, creep=None, sample_time=DT, disturbance_modes="spectrum")
    fit = est.fit(recs)
    near = _light_poles_hz(fit.model)
    assert np.any(np.abs(near - 1500.0) < 0.02 * 1500.0), near
    assert len(fit.modes) == 1
    mode = fit.modes[0]
    assert abs(mode.frequency_hz - 1500.0) < 0.02 * 1500.0
    assert 0.02 / 1.5 < mode.damping < 0.02 * 1.5
    assert fit.model.disturbance_modes == ((mode.frequency_hz, mode.damping),)
    assert "mode from the disturbance spectrum" in fit.summary()
    # the step off: the input-output fit alone does not find the mode
    off = StageIdentifier("preisach", n_levels=8, dynamics=2, creep=None, sample_time=DT, disturbance_modes=None)
    plain = off.fit(recs)
    assert plain.modes == () and not np.any(np.abs(_light_poles_hz(plain.model) - 1500.0) < 150.0)
    auto = StageIdentifier("preisach", n_levels=8, dynamics=2, creep=None, sample_time=DT).fit(recs)
    assert auto.modes == () and "did not lower the held-out one-step prediction error" in auto.message


@pytest.mark.study
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_mode_without_a_resonance_in_the_noise(seed):
    """No resonance (a 1.5 kHz lag), disturbance and sensor noise; and a 900 Hz resonance the
    drives excite but no disturbance (sensor noise only): no mode is added."""
    p = np.exp(-2 * np.pi * 1500.0 * DT)
    recs = _records(np.r_[1 - p], np.r_[1.0, -p], ((20.0, 1.5), (100.0, 0.6)), seed=seed)
    fit = StageIdentifier("preisach", n_levels=8, dynamics=2, creep=None, sample_time=DT).fit(recs)
    assert fit.modes == () and fit.model.disturbance_modes == ()
    b, a = _resonance(900.0, 0.02)
    recs = _records(b, a, ((20.0, 1.5), (100.0, 0.6)), disturbance=0.0, seed=seed)
    fit = StageIdentifier("preisach", n_levels=8, dynamics=2, creep=None, sample_time=DT).fit(recs)
    assert fit.modes == ()


def test_white_residuals_never_give_a_mode_and_a_rung_mode_is_found():
    rng = np.random.default_rng(7)
    drives = [_drive(20.0, 1.5), _drive(100.0, 0.6)]
    for _ in range(30):
        assert disturbance_modes([rng.standard_normal(u.size) for u in drives], drives, DT) == ()
    b, a = _resonance(700.0, 0.015)
    rung = [lfilter(b, a, rng.standard_normal(u.size)) + 0.05 * rng.standard_normal(u.size) for u in drives]
    (mode,) = disturbance_modes(rung, drives, DT)
    assert abs(mode.frequency_hz - 700.0) < 14.0 and 0.01 < mode.damping < 0.0225
    # a pole already in the dynamics at that mode: not added again
    assert disturbance_modes(rung, drives, DT, poles=np.roots(a)) == ()
    # ... nor when the fit has it a little more damped than a mode (0.08 > MAX_DAMPING)
    assert disturbance_modes(rung, drives, DT, poles=np.roots(_resonance(700.0, 0.08)[1])) == ()
    # a well-damped pair far away does not hide it
    assert len(disturbance_modes(rung, drives, DT, poles=np.roots(_resonance(2500.0, 0.08)[1]))) == 1
    # a record too short for MIN_SEGMENTS segments takes no part
    assert disturbance_modes([r[:1500] for r in rung], [u[:1500] for u in drives], DT) == ()


def test_resonance_filter_has_unit_dc_gain_and_the_modes_poles():
    modes = (DisturbanceMode(700.0, 0.02, 10.0), DisturbanceMode(2100.0, 0.03, 8.0))
    b, a = resonance_filter(modes, DT)
    assert np.isclose(np.sum(b) / np.sum(a), 1.0)
    s = np.log(np.roots(a).astype(complex)) / DT
    np.testing.assert_allclose(np.sort(np.abs(s)) / (2 * np.pi), [700, 700, 2100, 2100], rtol=1e-9)


def test_stage_json_names_the_modes_and_refuses_bad_ones():
    b, a = _resonance(700.0, 0.02)
    g = transfer_to_statespace(b, a, DT)
    s = StageModel(_hysteresis(), g, disturbance_modes=((700.0, 0.02),))
    d = s.to_dict()
    assert d["disturbance_modes"] == [{"frequency_hz": 700.0, "damping": 0.02}]
    assert StageModel.from_dict(json.loads(json.dumps(d))).disturbance_modes == ((700.0, 0.02),)
    assert "disturbance_modes" not in StageModel(_hysteresis(), g).to_dict()
    with pytest.raises(ModelFormatError, match="disturbance_modes"):
        StageModel.from_dict({**d, "disturbance_modes": [{"frequency_hz": 700.0}]})
    with pytest.raises(ModelError, match="disturbance_modes"):
        StageModel(_hysteresis(), None, disturbance_modes=((700.0, 0.02),))
    with pytest.raises(ModelError, match="disturbance_modes"):
        StageModel(_hysteresis(), g, disturbance_modes=((700.0, -0.02),))


@pytest.mark.study
def test_cli_disturbance_modes_flag(tmp_path, capsys):
    b, a = _resonance(1500.0, 0.02)
    paths = []
    for k, (u, y) in enumerate(_records(b, a, SLOW)):
        p = tmp_path / f"r{k}.csv"
        write_csv(p, {"t": np.arange(u.size) * DT, "V": u, "y": y})
        paths.append(str(p))
    base = ["identify", "hysteresis", *paths, "--input", "V", "--output", "y", "--model", "preisach"]
    base += ["--levels", "8", "--dynamics", "2", "--creep", "none"]
    assert main([*base, "--disturbance-modes", "spectrum", "-o", str(tmp_path / "on.json")]) == 0
    assert "mode from the disturbance spectrum: 14" in capsys.readouterr().out  # 1498 Hz
    on = json.loads((tmp_path / "on.json").read_text())
    assert abs(on["disturbance_modes"][0]["frequency_hz"] - 1500.0) < 30.0
    assert main([*base, "--disturbance-modes", "none", "-o", str(tmp_path / "off.json")]) == 0
    assert "disturbance_modes" not in json.loads((tmp_path / "off.json").read_text())
    assert main([*base, "--disturbance-modes", "maybe", "-o", str(tmp_path / "bad.json")]) == 2
    assert not (tmp_path / "bad.json").exists()


@pytest.mark.study
@pytest.mark.slow
@pytest.mark.realdata
def test_measured_tracking_records_meet_the_target_with_the_mode_from_the_disturbance():
    """The dSPACE records (studies/hysteresis/RESULTS.md sections 4f-4i): a Preisach stage
    identified on the 20 + 100 Hz FORC records with order 1 and creep 0.05 s and the default
    ``disturbance_modes="auto"`` keeps a ~745 Hz mode from the records' disturbance: the FORC
    drives hardly excite it, and held out (each FORC record left out in turn) it raises the
    simulation error, but it lowers the one-step prediction error.  With it the 40 Hz FORC record
    stays within 1.5 % max and every tracking record within 1.0 % RMS; without the mode PRBN and
    the big sine miss (1.10 %, 2.48 %)."""
    from _dspace_records import dspace_record
    from stageid.hysteresis.stage.validation import validate_record

    train = [dspace_record(n)[:2] for n in ("20_hz_no_lp", "100_hz_no_lp")]
    fit = StageIdentifier("preisach", dynamics=1, creep=(0.05,), sample_time=DT).fit(train)
    assert len(fit.modes) == 1 and 700.0 < fit.modes[0].frequency_hz < 800.0, fit.summary()
    assert "lowered the held-out one-step prediction error" in fit.message
    assert validate_record(fit.model, *dspace_record("40_hz_no_lp"), "estimate").max_error_percent <= 1.5
    for name in ("tri50_1", "tri100_1", "sine50_1", "sine100_1", "prbn_1", "bigsine_1"):
        assert validate_record(fit.model, *dspace_record(name), "estimate").rms_error_percent <= 1.0, name
    off = StageIdentifier("preisach", dynamics=1, creep=(0.05,), sample_time=DT, disturbance_modes=None).fit(train)
    assert off.modes == ()
    assert validate_record(off.model, *dspace_record("bigsine_1"), "estimate").rms_error_percent > 1.0


@pytest.mark.study
@pytest.mark.slow
@pytest.mark.realdata
def test_the_40_and_100_hz_records_propose_the_mode_from_a_held_out_fit():
    """The dSPACE 40 + 100 Hz FORC records (studies/hysteresis/RESULTS.md section 4j), order 1,
    creep 0.05 s, default ``disturbance_modes="auto"``: the fit on both records leaves the ~745 Hz
    ring too low above its model error to be found, the fit on the 100 Hz record alone (a held-out
    fold of the selection) shows it; proposed from there, it lowers the held-out one-step
    prediction error and is kept.  Measured: every tracking record but the big sine within 1 %
    RMS (0.44-0.59 %), the big sine 1.35 % against 2.53 % without the mode (the target's 1 % is
    missed there: its error sits at the mode, and it depends on the mode's frequency and on the
    phase of the rest of the dynamics there, which the FORC records do not pin: section 4k)."""
    from _dspace_records import dspace_record
    from stageid.hysteresis.stage.validation import validate_record

    train = [dspace_record(n)[:2] for n in ("40_hz_no_lp", "100_hz_no_lp")]
    fit = StageIdentifier("preisach", dynamics=1, creep=(0.05,), sample_time=DT).fit(train)
    assert len(fit.modes) == 1 and 700.0 < fit.modes[0].frequency_hz < 800.0, fit.summary()
    assert "lowered the held-out one-step prediction error" in fit.message
    assert validate_record(fit.model, *dspace_record("20_hz_no_lp"), "estimate").max_error_percent <= 1.5
    for name in ("tri50_1", "tri100_1", "sine50_1", "sine100_1", "prbn_1"):
        assert validate_record(fit.model, *dspace_record(name), "estimate").rms_error_percent <= 1.0, name
    off = StageIdentifier("preisach", dynamics=1, creep=(0.05,), sample_time=DT, disturbance_modes=None).fit(train)
    big = [
        validate_record(m, *dspace_record("bigsine_1"), "estimate").rms_error_percent for m in (fit.model, off.model)
    ]
    assert big[0] < 0.6 * big[1], big
