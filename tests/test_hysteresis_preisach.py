"""Discrete Preisach model: staircase kernel vs relay twin vs Everett sums, JSON, identification."""

import json

import numpy as np
import pytest

from stageid import DataError, ModelFormatError
from stageid.hysteresis.kernels.preisach import relays_reference
from stageid.hysteresis.preisach import PreisachModel, demagnetized_counts, everett, everett_output
from stageid.hysteresis.preisach_identification import PreisachIdentifier, relay_regressors
from stageid.hysteresis.serialization import model_from_dict


def _random_model(seed, n=7):
    rng = np.random.default_rng(seed)
    return PreisachModel((-1.0, 1.0), rng.random(n * (n + 1) // 2), output_offset=rng.standard_normal())


def _walk(seed, n=400):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.standard_normal(n)) * 0.2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_staircase_kernel_equals_relay_by_relay_twin(seed):
    m = _random_model(seed)
    u = _walk(seed)
    up0 = np.zeros(m.weights.size, dtype=bool)
    # same relays, same comparisons: only the summation order differs (rounding, 1e-12)
    np.testing.assert_allclose(m(u), relays_reference(u, m.levels, m.weights, up0) + m.output_offset, atol=1e-12)


def test_inputs_on_the_thresholds_switch_like_the_twin():
    m = _random_model(3, n=5)
    u = np.repeat(m.levels, 2)[::-1].copy()  # exactly on every threshold, falling then rising
    u = np.r_[u, u[::-1]]
    up0 = np.zeros(m.weights.size, dtype=bool)
    np.testing.assert_allclose(m(u), relays_reference(u, m.levels, m.weights, up0) + m.output_offset, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 4])
def test_everett_differences_equal_the_relay_sum(seed):
    m = _random_model(seed)
    u = _walk(seed + 10)
    np.testing.assert_allclose(everett_output(m, u), m(u), atol=1e-12)


def test_everett_is_the_weight_of_the_triangle():
    m = _random_model(5, n=4)  # levels -0.75, -0.25, 0.25, 0.75
    W = m.weight_matrix()
    # alpha <= 0.3 keeps rows 0..2, beta > -0.5 keeps columns 1..3 -> cells (1,1), (2,1), (2,2)
    assert everett(m, 0.3, -0.5) == pytest.approx(W[1, 1] + W[2, 1] + W[2, 2], abs=1e-15)
    assert everett(m, -1.0, -2.0) == 0.0


def test_major_loop_is_hysteretic_and_wipes_out():
    m = PreisachModel((0.0, 2.0), [0.0, 1.0, 0.0])  # one relay alpha 1.5, beta 0.5
    assert m(np.array([0.0, 1.0, 2.0, 1.0, 0.0])).tolist() == [0.0, 0.0, 1.0, 1.0, 0.0]


def test_state_resumes_the_run():
    m = _random_model(6)
    u = _walk(6)
    y, counts = m.run(u[:150])
    y2, _ = m.with_state(counts).run(u[150:])
    np.testing.assert_array_equal(np.r_[y, y2], m(u))


def test_json_round_trip_is_byte_stable():
    from stageid.models.serialization import dumps

    m = _random_model(7).with_state(demagnetized_counts(_random_model(7).levels, 0.1))
    text = dumps(m.to_dict())
    back = model_from_dict(json.loads(text))
    assert isinstance(back, PreisachModel)
    assert dumps(back.to_dict()) == text
    np.testing.assert_array_equal(back(_walk(1)), m(_walk(1)))


@pytest.mark.parametrize(
    "field, value", [("weights", [1.0, True, 2.0]), ("n_levels", 3), ("state", [0, 5]), ("input_range", [1.0, 0.0])]
)
def test_bad_json_fields_are_one_line(field, value):
    d = PreisachModel((0.0, 2.0), [0.0, 1.0, 0.0]).to_dict()
    d[field] = value
    with pytest.raises(ModelFormatError) as info:
        model_from_dict(d)
    assert "\n" not in str(info.value)


def test_identification_recovers_a_preisach_model_on_its_grid():
    rng = np.random.default_rng(0)
    n = 6
    true = PreisachModel((-1.0, 1.0), rng.random(n * (n + 1) // 2), output_offset=0.3)
    # first-order reversal curves: up to every cell's alpha, down to every beta below it
    h = 2.0 / n
    legs = [np.linspace(0.0, -1.0, 20)]
    for i, a in enumerate(true.levels):
        for b in true.levels[: i + 1][::-1]:  # peak just above alpha_i, trough just below beta_j
            p, q = a + h / 4, b - h / 4
            legs += [np.linspace(-1.0, p, 30), np.linspace(p, q, 30), np.linspace(q, -1.0, 30)]
    u = np.concatenate(legs)
    m0 = true.with_state(true.consistent_state(u[0]))
    y = m0(u)
    fit = PreisachIdentifier(n_levels=n, smoothing=0.0, input_range=(-1.0, 1.0)).fit((u, y))
    # noise-free data on the model's own grid: the relay weights themselves come back
    np.testing.assert_allclose(fit.model.weights, true.weights, atol=1e-6)
    assert fit.max_error_percent[0] < 1e-6


def test_regressors_reproduce_the_model():
    m = _random_model(8)
    u = _walk(8)
    Phi = relay_regressors(u, m.levels)
    m0 = m.with_state(demagnetized_counts(m.levels, u[0]))
    np.testing.assert_allclose(Phi @ m.weights + m.output_offset, m0(u), atol=1e-12)


def test_grid_finer_than_the_data_is_one_data_error():
    u = np.r_[np.linspace(0, 1, 50), np.linspace(1, -1, 100)]  # one reversal only
    y = u**3
    with pytest.raises(DataError, match="finer than the records resolve") as info:
        PreisachIdentifier(n_levels=12).fit((u, y))
    assert "\n" not in str(info.value)
