"""`stageid validate`: JSON contract, text summary, report, and bad input (exit 2, one line, no file)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from _validation_plant import DT, modes, record
from stageid.cli.main import main
from stageid.data.io import write_csv
from stageid.models import save_model


def _files(tmp_path, seed=0, n=4000):
    exp = record(seed, n=n)
    write_csv(tmp_path / "rec.csv", {"u": exp.u[:, 0], "y": exp.y[:, 0]}, dt=DT)
    save_model(modes(), tmp_path / "true.json")
    save_model(modes((0,)), tmp_path / "low.json")
    return str(tmp_path / "rec.csv")


@pytest.mark.parametrize("seed", range(3))
def test_true_model_passes_and_json_matches_contract(tmp_path, capsys, seed):
    rec = _files(tmp_path, seed)
    out = tmp_path / "v.json"
    assert main(["validate", str(tmp_path / "true.json"), rec, "--json", str(out)]) == 0
    y = json.loads(out.read_text())["outputs"]["y"]
    for key in ("fit_percent", "nrmse", "whiteness", "independence"):
        assert key in y
    for test in ("whiteness", "independence"):
        assert set(y[test]) >= {"pass", "max_abs", "bound", "lags"}
        assert y[test]["pass"] is True
    assert y["independence"]["inputs"]["u"]["pass"] is True
    text = capsys.readouterr().out
    assert "y: fit" in text and "whiteness pass" in text and "independence pass" in text


@pytest.mark.parametrize("seed", range(3))
def test_model_missing_a_mode_fails_a_test(tmp_path, capsys, seed):
    rec = _files(tmp_path, seed)
    out = tmp_path / "v.json"
    assert main(["validate", str(tmp_path / "low.json"), rec, "--json", str(out)]) == 0
    y = json.loads(out.read_text())["outputs"]["y"]
    assert not (y["whiteness"]["pass"] and y["independence"]["pass"])
    assert "FAIL" in capsys.readouterr().out


def test_report_draws_one_resid_figure_per_output(tmp_path):
    rec = _files(tmp_path)
    assert main(["validate", str(tmp_path / "true.json"), rec, "--report", str(tmp_path / "rep")]) == 0
    html = (tmp_path / "rep" / "index.html").read_text()
    assert html.count("<img src='data:image/png;base64,") == 1
    assert "autocorrelation" in html
    metrics = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert metrics["outputs"]["y"]["whiteness"]["pass"] is True


def test_column_mapping(tmp_path):
    exp = record(1)
    write_csv(tmp_path / "r.csv", {"V": exp.u[:, 0], "z": exp.y[:, 0]}, dt=DT)
    save_model(modes(), tmp_path / "m.json")
    args = ["validate", str(tmp_path / "m.json"), str(tmp_path / "r.csv"), "--inputs", "V", "--outputs", "z"]
    assert main([*args, "--json", str(tmp_path / "o.json")]) == 0
    assert "y" in json.loads((tmp_path / "o.json").read_text())["outputs"]


def test_file_without_time_column_takes_the_discrete_models_sample_time(tmp_path):
    exp = record(2)
    write_csv(tmp_path / "with_t.csv", {"u": exp.u[:, 0], "y": exp.y[:, 0]}, dt=DT)
    write_csv(tmp_path / "no_t.csv", {"u": exp.u[:, 0], "y": exp.y[:, 0]})
    assert "t" not in (tmp_path / "no_t.csv").read_text().splitlines()[0].split(",")
    save_model(modes(), tmp_path / "m.json")
    for name in ("with_t", "no_t"):
        assert (
            main(
                [
                    "validate",
                    str(tmp_path / "m.json"),
                    str(tmp_path / f"{name}.csv"),
                    "--json",
                    str(tmp_path / f"{name}.json"),
                ]
            )
            == 0
        )
    assert json.loads((tmp_path / "no_t.json").read_text()) == json.loads((tmp_path / "with_t.json").read_text())


def _bad(tmp_path, capsys, args):
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    return err


def test_channels_not_matching_the_model(tmp_path, capsys):
    exp = record(0)
    write_csv(tmp_path / "r.csv", {"V": exp.u[:, 0], "z": exp.y[:, 0]}, dt=DT)
    save_model(modes(), tmp_path / "m.json")
    err = _bad(
        tmp_path,
        capsys,
        [
            "validate",
            str(tmp_path / "m.json"),
            str(tmp_path / "r.csv"),
            "--json",
            str(tmp_path / "o.json"),
            "--report",
            str(tmp_path / "rep"),
        ],
    )
    assert "u" in err


def test_too_few_samples_for_the_lags(tmp_path, capsys):
    rec = _files(tmp_path, n=60)
    err = _bad(
        tmp_path,
        capsys,
        [
            "validate",
            str(tmp_path / "true.json"),
            rec,
            "--json",
            str(tmp_path / "o.json"),
            "--report",
            str(tmp_path / "rep"),
        ],
    )
    assert "at least 104 samples" in err


def test_wrong_sample_time(tmp_path, capsys):
    exp = record(0)
    write_csv(tmp_path / "r.csv", {"u": exp.u[:, 0], "y": exp.y[:, 0]}, dt=2 * DT)
    save_model(modes(), tmp_path / "m.json")
    err = _bad(
        tmp_path,
        capsys,
        ["validate", str(tmp_path / "m.json"), str(tmp_path / "r.csv"), "--json", str(tmp_path / "o.json")],
    )
    assert "sample time" in err


def test_json_must_be_json(tmp_path, capsys):
    rec = _files(tmp_path)
    _bad(tmp_path, capsys, ["validate", str(tmp_path / "true.json"), rec, "--json", str(tmp_path / "o.csv")])


def test_count_of_renamed_channels(tmp_path, capsys):
    rec = _files(tmp_path)
    _bad(tmp_path, capsys, ["validate", str(tmp_path / "true.json"), rec, "--inputs", "a,b"])


def test_constant_input_is_bad_input(tmp_path, capsys):
    write_csv(tmp_path / "r.csv", {"u": np.zeros(500), "y": np.random.default_rng(0).standard_normal(500)}, dt=DT)
    save_model(modes(), tmp_path / "m.json")
    _bad(tmp_path, capsys, ["validate", str(tmp_path / "m.json"), str(tmp_path / "r.csv")])


def test_hysteresis_model_reports_error_in_percent_of_range_and_the_loop(tmp_path, capsys):
    from stageid.hysteresis import PIModel

    model = PIModel(r=[0.0, 20.0, 40.0], weights=[0.01, 0.005, 0.002])
    save_model(model, tmp_path / "pi.json")
    rng = np.random.default_rng(0)
    v = 50.0 * (1 - np.cos(np.linspace(0, 8 * np.pi, 2000)))
    y = model.simulate(v[:, None])[:, 0]
    write_csv(tmp_path / "tri.csv", {"V": v, "y": y + 0.002 * np.ptp(y) * rng.standard_normal(2000)}, dt=0.001)
    args = ["validate", str(tmp_path / "pi.json"), str(tmp_path / "tri.csv"), "--inputs", "V", "--outputs", "y"]
    assert main([*args, "--json", str(tmp_path / "o.json"), "--report", str(tmp_path / "rep")]) == 0
    out = json.loads((tmp_path / "o.json").read_text())["outputs"]["y"]
    # 0.2 % of range white noise: RMS error ~0.2 %, max ~0.8 % (about 4 sigma over 2000 samples)
    assert 0.15 < out["rms_error_percent"] < 0.25
    assert out["max_error_percent"] < 1.0
    assert "% of range" in capsys.readouterr().out
    html = (tmp_path / "rep" / "index.html").read_text()
    assert html.count("<img src='data:image/png;base64,") == 2  # the resid figure and the loop
    assert "Hysteresis loops" in html
