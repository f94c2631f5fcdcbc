"""Residual tests: calibration of both chi-square tests, power against a model missing modes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter
from scipy.stats import binom

from _validation_plant import DT, modes, record
from stageid._errors import DataError
from stageid.data import Experiment
from stageid.models import StateSpaceModel
from stageid.validation.residuals import independence_test, validate_model, validation_json, whiteness_test

N_SEEDS = 200
ALPHA = 0.01


def _window(n: int = N_SEEDS, p: float = 1 - ALPHA) -> tuple[int, int]:
    """Central 99.9 % binomial window of passes for a test that passes with probability p."""
    return int(binom.ppf(0.0005, n, p)), int(binom.ppf(0.9995, n, p))


def test_whiteness_calibrated_on_white_noise():
    passes = sum(whiteness_test([np.random.default_rng(s).standard_normal(2000)]).passed for s in range(N_SEEDS))
    lo, hi = _window()
    assert lo <= passes <= hi


def test_independence_calibrated_with_a_coloured_input():
    # a smooth input makes the raw lags strongly correlated; the prewhitened statistic must still be chi2
    passes = 0
    for s in range(N_SEEDS):
        rng = np.random.default_rng(s)
        u = lfilter([1.0], [1.0, -0.95], rng.standard_normal(2000))
        passes += independence_test([rng.standard_normal(2000)], [u]).passed
    lo, hi = _window()
    assert lo <= passes <= hi


def test_true_model_passes_about_99_percent_over_seeds():
    """The true plant on noisy records: each test passes within the binomial window of 99 %."""
    true = modes()
    white = indep = 0
    for s in range(N_SEEDS):
        out = validate_model(true, [record(s)])["outputs"]["y"]
        white += out["whiteness"].passed
        indep += out["independence"]["u"].passed
    lo, hi = _window()
    assert lo <= white <= hi, white
    assert lo <= indep <= hi, indep


@pytest.mark.parametrize("seed", range(5))
def test_model_missing_a_mode_fails(seed):
    result = validation_json(validate_model(modes((0,)), [record(seed)]))["outputs"]["y"]
    assert not (result["whiteness"]["pass"] and result["independence"]["pass"])


@pytest.mark.parametrize("seed", range(5))
def test_true_model_passes_with_json_keys(seed):
    result = validation_json(validate_model(modes(), [record(seed), record(seed + 100)]))["outputs"]["y"]
    assert result["whiteness"]["pass"] and result["independence"]["pass"]
    assert result["fit_percent"] > 85  # 10 % white noise: fit = 100 (1 - ~0.1)
    assert result["whiteness"]["lags"] == list(range(1, 26))
    assert result["independence"]["lags"] == list(range(0, 26))
    assert result["whiteness"]["bound"] == pytest.approx(2.5758 / np.sqrt(8000), rel=1e-3)
    assert result["whiteness"]["max_abs"] == pytest.approx(max(abs(c) for c in result["whiteness"]["correlations"]))


def test_delayed_dependence_is_detected():
    rng = np.random.default_rng(3)
    u = lfilter([1.0], [1.0, -0.9], rng.standard_normal(3000))
    e = 0.05 * np.roll(u, 5) + rng.standard_normal(3000)
    assert not independence_test([e], [u]).passed


def test_too_few_samples_for_the_lags():
    with pytest.raises(DataError, match="at least 104 samples"):
        whiteness_test([np.random.default_rng(0).standard_normal(80)])


def test_constant_residual_refused():
    with pytest.raises(DataError, match="vary"):
        whiteness_test([np.ones(500)])


def test_channels_must_match_the_model():
    exp = record(0).with_(output_names=("z",))
    with pytest.raises(DataError, match="the model expects"):
        validate_model(modes(), [exp])


def _mimo(which=(0, 1)):
    """Two inputs, two outputs: each output sees both modes of ``which`` driven by both inputs."""
    siso = modes(which)
    B = np.column_stack([siso.B[:, 0], -0.5 * siso.B[:, 0]])
    C = np.vstack([siso.C[0], np.roll(siso.C[0], 1)])
    return StateSpaceModel(siso.A, B, C, np.zeros((2, 2)), dt=DT, inputs=("u1", "u2"), outputs=("y1", "y2"))


@pytest.mark.parametrize("seed", range(4))
def test_mimo_true_model_passes_every_output_and_input(seed):
    rng = np.random.default_rng(seed)
    u = lfilter([1.0], [1.0, -0.9], rng.standard_normal((4000, 2)), axis=0)
    y = _mimo().simulate(u)
    y = y + 0.1 * y.std(axis=0) * rng.standard_normal(y.shape)
    exp = Experiment(u=u, y=y, dt=DT, input_names=("u1", "u2"), output_names=("y1", "y2"))
    out = validation_json(validate_model(_mimo(), [exp]))["outputs"]
    assert set(out) == {"y1", "y2"}
    for entry in out.values():
        assert set(entry["independence"]["inputs"]) == {"u1", "u2"}
        assert entry["whiteness"]["pass"] and entry["independence"]["pass"]
    low = validation_json(validate_model(_mimo((0,)), [exp]))["outputs"]
    assert any(not (e["whiteness"]["pass"] and e["independence"]["pass"]) for e in low.values())


def test_records_too_short_for_the_prewhitening_refused():
    rng = np.random.default_rng(0)
    es, us = [rng.standard_normal(20) for _ in range(10)], [rng.standard_normal(20) for _ in range(10)]
    with pytest.raises(DataError, match="records of more than 36 samples"):
        independence_test(es, us)
