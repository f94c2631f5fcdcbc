"""Multisine design: line sets with detection lines, realisations, crest factor, band shape, orthogonal MIMO."""

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import run_main
from stageid import SignalError
from stageid.cli.main import cli
from stageid.signals import crest_factor, multisine, multisine_lines, multisine_plan
from stageid.signals.multisine import orthogonal_matrix

N, DT, LO, HI, P = 4096, 1e-3, 1.0, 200.0, 4


def _line_power(x, periods=P):
    """Power per line of one period's grid (the record holds whole periods)."""
    X = np.fft.rfft(np.asarray(x).reshape(periods, -1, *np.shape(x)[1:]).mean(axis=0), axis=0)
    return np.abs(X) ** 2


def test_odd_lines_put_energy_on_odd_lines_only_and_list_the_even_ones_as_detection():
    x = multisine(N, DT, LO, HI, lines="odd", seed=3, n_periods=P)
    plan = multisine_plan(N, DT, LO, HI, n_periods=P, lines="odd")
    power = _line_power(x)
    on = np.zeros(power.size, bool)
    on[plan.excited] = True
    assert np.all(plan.excited % 2 == 1) and np.all(plan.detection_even % 2 == 0)
    assert power[~on].sum() < 1e-20 * power.sum()
    band = multisine_lines(N, DT, LO, HI, P)
    assert sorted([*plan.excited, *plan.detection_even]) == band.tolist()


def test_random_odd_leaves_one_line_per_group_and_keeps_it_across_realisations():
    plan = multisine_plan(N, DT, LO, HI, n_periods=P, lines="random-odd", detection_group=4, seed=5)
    odd = multisine_lines(N, DT, LO, HI, P)
    odd = odd[odd % 2 == 1]
    assert sorted([*plan.excited, *plan.detection_odd]) == odd.tolist()
    for g in np.array_split(odd, np.arange(4, odd.size, 4)):
        assert np.isin(g, plan.detection_odd).sum() == (1 if g.size > 1 else 0)
    # other seeds pick other lines
    assert not np.array_equal(plan.detection_odd, multisine_plan(N, DT, LO, HI, P, "random-odd", seed=6).detection_odd)
    a, b = (multisine(N, DT, LO, HI, lines="random-odd", seed=5, n_periods=P, realisation=r) for r in (0, 1))
    pa, pb = _line_power(a), _line_power(b)
    pa, pb = pa / pa.sum(), pb / pb.sum()  # each realisation is scaled to its own peak
    # same lines and the same amplitude spectrum, other phases
    np.testing.assert_allclose(pa, pb, rtol=1e-9, atol=1e-12 * pa.max())
    assert np.flatnonzero(pa > 1e-12 * pa.max()).tolist() == plan.excited.tolist()
    assert np.max(np.abs(a - b)) > 0.1 * np.max(np.abs(a))


def test_realisation_zero_is_the_seeded_multisine_of_before_and_others_need_an_integer_seed():
    # the first realisation draws its phases exactly as the single random-phase multisine did
    rng = np.random.default_rng(2)
    lines = multisine_lines(1000, DT, 1.0, 100.0)
    phases = rng.uniform(0.0, 2 * np.pi, size=(lines.size, 1))
    t = np.arange(1000) * DT
    ref = np.cos(2 * np.pi * np.outer(t, lines / (1000 * DT)) + phases[:, 0]).sum(axis=1)
    np.testing.assert_allclose(multisine(1000, DT, 1.0, 100.0, seed=2), ref / np.abs(ref).max(), atol=1e-12)
    with pytest.raises(SignalError, match=re.escape("realisation 2 of multisine needs an integer `seed`; got None")):
        multisine(1000, DT, 1.0, 100.0, realisation=2)


def test_clipping_lowers_the_crest_factor_below_schroeder_and_keeps_the_amplitude_spectrum():
    schroeder = multisine(N, DT, LO, HI, kind="schroeder")
    clipped = multisine(N, DT, LO, HI, seed=1, crest_iterations=150)
    assert crest_factor(clipped) < crest_factor(schroeder) - 0.1  # 1.76 for Schroeder on these 819 lines
    assert crest_factor(multisine(N, DT, LO, HI, seed=1)) > 3.0  # the random start it came from
    power = _line_power(clipped, 1)
    lines = multisine_lines(N, DT, LO, HI)
    np.testing.assert_allclose(power[lines], power[lines].mean(), rtol=1e-9)


def test_band_shape_sets_the_line_amplitudes_on_log_log_axes():
    x = multisine(N, DT, LO, HI, seed=1, shape="10:1,100:0.1", n_periods=P)
    plan = multisine_plan(N, DT, LO, HI, n_periods=P)
    f = plan.excited / (plan.samples_per_period * DT)
    amp = np.sqrt(_line_power(x)[plan.excited])
    amp /= amp[np.argmin(np.abs(f - 5.0))]
    expected = np.clip(10 ** (-(np.log10(np.clip(f, 10, 100)) - 1)), 0.1, 1.0)  # -20 dB/decade from 10 to 100 Hz
    np.testing.assert_allclose(amp, expected, rtol=1e-9)
    with pytest.raises(SignalError, match="increasing frequencies"):
        multisine(N, DT, LO, HI, shape="100:1,10:1")


@pytest.mark.parametrize("n_inputs, n_experiments", [(2, 2), (3, 3), (4, 4)])
def test_orthogonal_design_excites_every_input_independently_at_every_line(n_inputs, n_experiments):
    T = orthogonal_matrix(n_inputs)
    assert T.shape == (n_inputs, n_experiments)
    np.testing.assert_allclose(T @ T.conj().T, n_experiments * np.eye(n_inputs), atol=1e-12)
    plan = multisine_plan(1024, DT, 1.0, 100.0, n_inputs=n_inputs, mimo="orthogonal")
    assert plan.n_experiments == n_experiments
    U = np.stack(
        [
            np.fft.rfft(
                multisine(1024, DT, 1.0, 100.0, seed=4, n_channels=n_inputs, mimo="orthogonal", experiment=e), axis=0
            )
            for e in range(n_experiments)
        ],
        axis=-1,
    )[plan.excited]  # (lines, inputs, experiments)
    # unit-modulus phases times an orthogonal matrix: well conditioned up to each record's own
    # peak scaling (the independent design drives every experiment alike: singular)
    assert np.max(np.linalg.cond(U)) < 2.0
    U_same = np.stack(
        [np.fft.rfft(multisine(1024, DT, 1.0, 100.0, seed=4, n_channels=n_inputs), axis=0)] * n_experiments, -1
    )
    assert np.min(np.linalg.cond(U_same[plan.excited])) > 1e12
    with pytest.raises(SignalError, match="`experiment` of multisine must be below"):
        multisine(1024, DT, 1.0, 100.0, n_channels=n_inputs, mimo="orthogonal", experiment=n_experiments)


def test_cli_writes_one_file_per_realisation_and_experiment_and_the_design(tmp_path):
    out = tmp_path / "ms.csv"
    args = "--n-samples 2048 --dt 1e-3 --f-low 1 --f-high 50 --n-periods 2 --lines random-odd --seed 3"
    res = CliRunner().invoke(
        cli,
        [
            "signal",
            "multisine",
            *args.split(),
            "--n-channels",
            "2",
            "--mimo",
            "orthogonal",
            "--realisations",
            "3",
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    design = json.loads((tmp_path / "ms.multisine.json").read_text())
    names = sorted(p.name for p in tmp_path.glob("ms_r*.csv"))
    assert names == [f"ms_r{r:02d}_e{e}.csv" for r in (1, 2, 3) for e in (1, 2)]
    assert [f["file"] for f in design["files"]] == names
    plan = multisine_plan(2048, 1e-3, 1.0, 50.0, 2, "random-odd", seed=3, n_inputs=2, mimo="orthogonal")
    assert design["excited_lines"] == plan.excited.tolist()
    assert design["detection_odd_lines"] == plan.detection_odd.tolist()
    assert design["experiments_per_realisation"] == 2 and design["seed"] == 3
    # the plain command keeps writing the one file it was asked for
    plain = tmp_path / "plain.csv"
    res = CliRunner().invoke(cli, ["signal", "multisine", *args.split(), "-o", str(plain)])
    assert res.exit_code == 0, res.output
    assert plain.exists() and not list(tmp_path.glob("plain_r*"))


def test_cli_refuses_realisations_of_deterministic_phases(tmp_path):
    args = "--n-samples 1024 --dt 1e-3 --f-low 1 --f-high 50 --kind schroeder --realisations 2"
    rc, out, err = run_main("signal", "multisine", *args.split(), "-o", tmp_path / "s.csv")
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "--realisations 2 needs --kind random-phase" in err
    assert not list(tmp_path.iterdir())
