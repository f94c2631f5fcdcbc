"""A new user's first commands: what they are told when a record does not fit the model or the
command, and what the commands print where."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_main
from stageid.data.io import read_table, write_csv
from stageid.models import StateSpaceModel, save_model


@pytest.fixture
def two_input_model(tmp_path):
    """A stable discrete 3-state model (poles 0.9, 0.5, -0.3) with inputs Z, Rx and outputs z, rx."""
    A, B = np.diag([0.9, 0.5, -0.3]), np.array([[1.0, 0.2], [0.0, 1.0], [0.5, -0.5]])
    g = StateSpaceModel(A, B, [[1.0, 0.5, 0.0], [0.0, 1.0, 1.0]], np.zeros((2, 2)), 0.01, ("Z", "Rx"), ("z", "rx"))
    save_model(g, tmp_path / "g.json")
    return g


def test_simulate_names_the_inputs_a_record_lacks(tmp_path, two_input_model):
    write_csv(tmp_path / "z.csv", {"Z": np.ones(100)}, dt=0.01)
    code, out, err = run_main("simulate", "g.json", "z.csv", "-o", "y.csv", cwd=tmp_path)
    assert code == 2 and not (tmp_path / "y.csv").exists()
    assert "input(s) Rx" in err and "its columns: Z" in err and "--zero-missing" in err and len(err.splitlines()) == 1


def test_simulate_zero_missing_holds_the_absent_inputs_at_zero_and_says_so(tmp_path, two_input_model):
    u = np.random.default_rng(6).standard_normal(200)
    write_csv(tmp_path / "z.csv", {"Z": u}, dt=0.01)
    code, out, err = run_main("simulate", "g.json", "z.csv", "--zero-missing", "-o", "y.csv", cwd=tmp_path)
    assert code == 0, err
    assert "Rx" in err and "held at 0" in err
    expected = two_input_model.simulate(np.column_stack([u, np.zeros_like(u)]))
    np.testing.assert_allclose(read_table(tmp_path / "y.csv").values, expected, atol=1e-9)


def _record(path, u, y, dt=0.01):
    write_csv(path, {"Z": u[:, 0], "Rx": u[:, 1], "z": y[:, 0], "rx": y[:, 1]}, dt=dt)


def test_validate_tests_the_moving_input_and_names_the_constant_one(tmp_path, two_input_model):
    rng = np.random.default_rng(7)
    u = np.column_stack([rng.standard_normal(2000), np.zeros(2000)])  # a one-axis record: Rx never moves
    _record(tmp_path / "one-axis.csv", u, two_input_model.simulate(u) + 0.01 * rng.standard_normal((2000, 2)))
    code, out, err = run_main("validate", "g.json", "one-axis.csv", "--json", "v.json", cwd=tmp_path)
    assert code == 0, err
    assert "[Rx: constant in the record, not tested]" in out and "[Z: chi2" in out

    z = json.loads((tmp_path / "v.json").read_text())["outputs"]["z"]
    assert z["untested_inputs"] == ["Rx"] and set(z["independence"]["inputs"]) == {"Z"}


def test_validate_names_the_record_when_no_input_moves(tmp_path, two_input_model):
    _record(tmp_path / "still.csv", np.zeros((500, 2)), np.random.default_rng(8).standard_normal((500, 2)))
    code, out, err = run_main("validate", "g.json", "still.csv", cwd=tmp_path)
    assert code == 2 and len(err.splitlines()) == 1
    assert "every input (Z, Rx) is constant in record 'still.csv'" in err


def test_validate_prints_one_line_per_record_and_output_then_the_pooled_lines(tmp_path, two_input_model):
    rng = np.random.default_rng(9)
    for name in ("a.csv", "b.csv"):
        u = rng.standard_normal((1500, 2))
        _record(tmp_path / name, u, two_input_model.simulate(u) + 0.01 * rng.standard_normal((1500, 2)))
    code, out, err = run_main("validate", "g.json", "a.csv", "b.csv", "--json", "v.json", cwd=tmp_path)
    assert code == 0, err
    starts = [line.split(": fit")[0] for line in out.splitlines()]
    assert starts == ["a.csv  z", "a.csv  rx", "b.csv  z", "b.csv  rx", "all 2 records  z", "all 2 records  rx"]

    records = json.loads((tmp_path / "v.json").read_text())["records"]
    assert [r["record"] for r in records] == ["a.csv", "b.csv"] and "whiteness" in records[0]["outputs"]["z"]


def test_validate_names_its_error_measure_rms_in_percent_of_range_not_nrmse(tmp_path, two_input_model):
    rng = np.random.default_rng(10)
    u = rng.standard_normal((1500, 2))
    y = two_input_model.simulate(u)
    noisy = y + 0.01 * rng.standard_normal(y.shape)
    _record(tmp_path / "r.csv", u, noisy)
    code, out, err = run_main("validate", "g.json", "r.csv", cwd=tmp_path)
    rms_percent = 100 * np.sqrt(np.mean((noisy[:, 0] - y[:, 0]) ** 2)) / np.ptp(noisy[:, 0])
    assert code == 0 and f"RMS error {rms_percent:.3g} % of range" in out and "NRMSE" not in out
    code, help_text, _ = run_main("validate", "--help")
    assert "NRMSE" not in help_text and "% of the measured range" in help_text


def test_validate_initial_estimate_explains_a_record_started_away_from_rest(tmp_path, two_input_model):
    g, rng = two_input_model, np.random.default_rng(11)
    u = rng.standard_normal((1500, 2))
    x0 = 20.0 * rng.standard_normal(g.n_states)  # the stage was moving when the record started
    _record(tmp_path / "r.csv", u, g.simulate(u, x0=x0) + 0.01 * rng.standard_normal((1500, 2)))
    fits = {}
    for initial in ("model", "estimate"):
        code, out, err = run_main("validate", "g.json", "r.csv", "--initial", initial, "--json", "v.json", cwd=tmp_path)
        assert code == 0, err

        summary = json.loads((tmp_path / "v.json").read_text())
        assert summary["initial"]["method"] == initial
        fits[initial] = min(o["fit_percent"] for o in summary["outputs"].values())
    assert fits["estimate"] > 99.0 and fits["model"] < 90.0, fits
    code, out, err = run_main("validate", "g.json", "r.csv", "--initial", "kinds", cwd=tmp_path)
    assert code == 2 and "an LTI model takes model or estimate" in err


def test_estimated_initial_state_reproduces_the_free_response_of_a_continuous_model():
    from stageid.validation.initial_state import estimate_initial_state

    g = StateSpaceModel([[0.0, 1.0], [-400.0, -4.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], dt=None)
    u = np.random.default_rng(12).standard_normal((800, 1))
    y = g.simulate(u, x0=[1.0, -5.0], dt=0.001)
    np.testing.assert_allclose(estimate_initial_state(g, u, y, dt=0.001), [1.0, -5.0], rtol=1e-6)


def test_the_experiments_of_one_seed_have_different_noise():
    from stageid.plants import piezo_stage

    noise = []
    for name in ("chirp-z", "chirp-rx"):
        exp = piezo_stage.EXPERIMENTS[name](seed=0)
        noise.append((exp.y - piezo_stage.model().simulate(exp.u))[:, 0])
    # independent white noise: |correlation| about 1/sqrt(5000) = 0.014; the same noise gives 1
    assert abs(np.corrcoef(noise[0], noise[1])[0, 1]) < 0.1


def test_the_maglev_experiments_of_one_seed_have_different_noise():
    from stageid.plants import maglev

    noise = []
    for axis in ("x", "y"):
        measured = maglev.EXPERIMENTS[f"chirp-{axis}"](seed=0).column("phi")  # phi is not excited in either
        noise.append(measured - maglev.simulate_chirp(axis, snr_db=None).column("phi"))
    assert abs(np.corrcoef(noise[0], noise[1])[0, 1]) < 0.1


def test_the_true_p558_model_passes_whiteness_on_pooled_generated_records_at_the_tests_level():
    from stageid.plants import piezo_stage
    from stageid.validation.residuals import whiteness_test

    # 20 seeds x 3 outputs at the 1 % level: about 0.6 failures expected; 4 or more has probability 0.3 %
    # (the same noise in the three records made every pooled test fail: Q about 3x its chi2(25) mean)
    failures = 0
    for seed in range(20):
        exps = [piezo_stage.EXPERIMENTS[name](seed=seed) for name in ("chirp-z", "chirp-rx", "chirp-ry")]
        residuals = [e.y - piezo_stage.model().simulate(e.u) for e in exps]
        failures += sum(not whiteness_test([r[:, i] for r in residuals]).passed for i in range(3))
    assert failures <= 3, failures


def test_identify_hysteresis_takes_dynamics_0_the_order_auto_considers(tmp_path):
    from stageid.hysteresis import PIModel
    from stageid.signals import decaying_triangle

    u = decaying_triangle(20.0, 2, 1e-3, amplitude=10.0)[:2000]
    y = PIModel(r=[0.0, 2.5, 5.0, 7.5], weights=[1.0, 0.4, 0.2, 0.1]).simulate(u[:, None])[:, 0]
    write_csv(tmp_path / "a.csv", {"V": u, "y": y}, dt=1e-3)
    args = ("identify", "hysteresis", "a.csv", "--input", "V", "--output", "y", "--model", "pi", "--creep", "none")
    code, out, err = run_main(*args, "--dynamics", "0", "-o", "s.json", cwd=tmp_path)
    assert code == 0, err
    saved = json.loads((tmp_path / "s.json").read_text())
    assert saved["kind"] == "stage" and (saved["dynamics"] is None or saved["dynamics"]["A"] == [])
    assert "dynamics order 0" in out  # the summary is a result: stdout


def test_output_column_and_output_file_say_which_is_which(tmp_path):
    write_csv(tmp_path / "a.csv", {"V": np.linspace(0, 1, 300), "y": np.linspace(0, 2, 300)}, dt=1e-3)
    base = ("identify", "hysteresis", "a.csv", "--input", "V", "--output")
    code, out, err = run_main(*base, "hyst.json", cwd=tmp_path)  # the file given to the column option
    assert code == 2 and "--output names the output column" in err and "give it with -o" in err
    code, out, err = run_main(*base, "hyst.json", "-o", "h.json", cwd=tmp_path)
    assert code == 2 and "unknown column 'hyst.json'" in err and "the model file is -o/--output-file" in err
    code, out, err = run_main("plants", "p558", "-o", "z", cwd=tmp_path)  # a column name given to -o
    assert code == 2 and "-o names the file to write, not a data column" in err
    code, help_text, _ = run_main("identify", "hysteresis", "--help")
    assert "Output column of the records" in help_text and "--output names the output column" in help_text


def _help_texts(command=None, path=("stageid",)):
    import click

    from stageid.cli.main import cli

    command = command or cli
    ctx = click.Context(command, info_name=" ".join(path))
    yield " ".join(path), command.get_help(ctx)
    if isinstance(command, click.Group):
        for name in command.list_commands(ctx):
            yield from _help_texts(command.get_command(ctx, name), (*path, name))


def test_no_help_text_shows_docstring_markup():
    import re

    found = [
        f"{name}: {line.strip()}"
        for name, text in _help_texts()
        for line in text.splitlines()
        if "``" in line or re.search(r":[a-z]+:`", line)
    ]
    assert not found, "\n".join(found)


def _flexure_frd():
    """The 2x2 flexure stage of the FRF tests (modes at 80, 210 and 450 Hz), noise-free, 300 lines."""
    from stageid.frf import FrequencyResponse
    from test_frf_identify import flexure_stage

    g = flexure_stage()
    f = np.geomspace(5.0, 1000.0, 300)
    return FrequencyResponse(f, g.frequency_response(f), inputs=g.inputs, outputs=g.outputs)


def test_frd_fit_that_misses_the_flexure_warns_and_a_good_auto_fit_does_not():
    import warnings

    from stageid import FitWarning
    from stageid.frf import FRDIdentification

    frd = _flexure_frd()
    with pytest.warns(FitWarning, match=r"order-2 model \(as given\) misses the response by up to") as caught:
        low = FRDIdentification(order=2, sample_time=None).fit(frd)
    assert low.max_error > 0.1 and caught[0].filename == __file__  # pointed at the caller's line
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        auto = FRDIdentification(order="auto", sample_time=None).fit(frd)
    assert auto.max_error < 0.01 and auto.order >= 6


def test_frd_fit_within_the_datas_noise_does_not_warn():
    import warnings

    from stageid import FitWarning
    from stageid.frf import FRDIdentification, FrequencyResponse
    from test_frf_identify import noisy

    frd = _flexure_frd()
    G, std = noisy(frd.response, seed=3, level=0.2)  # misses of up to ~60 % of a peak, all noise
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        res = FRDIdentification(order=6, sample_time=None).fit(
            FrequencyResponse(frd.freqs, G, std, None, frd.inputs, frd.outputs)
        )
    assert res.max_error > 0.1  # against the noisy lines; the warning looks past 3 std of them


@pytest.mark.slow  # the order scan fits orders up to 20 to the measured response (~30 s)
@pytest.mark.realdata
def test_identify_frd_auto_on_the_afm_frf_does_not_pass_a_large_error_silently(tmp_path):
    import scipy.io

    from stageid.data import datasets
    from stageid.frf import FrequencyResponse, frd_columns

    path = None if datasets.SHARED_DATA is None else datasets.SHARED_DATA / "afm_piezo_stage_frf"
    if path is None or not (path / "FRF_data_current_stage2.mat").exists():
        pytest.skip("shared data folder not found (../shared/data/afm_piezo_stage_frf)")
    mat = scipy.io.loadmat(path / "FRF_data_current_stage2.mat", squeeze_me=True, struct_as_record=False)
    frf = mat["modelFit"].frf
    afm = FrequencyResponse(np.asarray(frf.freqs_Hz), np.asarray(frf.G_uz2stage), inputs=("uz",), outputs=("stage",))
    write_csv(tmp_path / "afm.csv", frd_columns(afm))
    code, out, err = run_main(
        "identify", "frd", "afm.csv", "--order", "auto", "--dt", "4e-5", "-o", "m.json", cwd=tmp_path
    )
    assert code == 0, err
    stated = float(out.split("(of its peak): uz ")[1].split(" %")[0])
    if stated > 10.0:  # the auto order leaves a large error: a one-line warning says so and what to try
        assert "stageid: warning: FRDIdentification: the order-" in err and "chosen by order='auto'" in err
        assert f"misses the response by up to {stated:.3g} %" in err
    else:
        assert "warning" not in err


def test_validate_gives_a_record_too_short_for_the_tests_its_fit_and_the_reason(tmp_path, two_input_model):
    rng = np.random.default_rng(13)
    for name, n in (("long.csv", 1500), ("short.csv", 60)):
        u = rng.standard_normal((n, 2))
        _record(tmp_path / name, u, two_input_model.simulate(u) + 0.01 * rng.standard_normal((n, 2)))
    code, out, err = run_main("validate", "g.json", "long.csv", "short.csv", cwd=tmp_path)
    assert code == 0, err
    short = [line for line in out.splitlines() if line.startswith("short.csv")]
    assert len(short) == 2 and all("no residual tests: residual tests over 25 lags need" in s for s in short)
    assert all("% of range" in s for s in short)
