"""Continuous-cell Preisach model: stack kernel vs cell-area twin vs Everett sums, states, JSON, identification."""

import json

import numpy as np
import pytest

from stageid import DataError, ModelFormatError
from stageid.hysteresis.kernels.preisach import cells_reference
from stageid.hysteresis.preisach import PreisachModel, demagnetizing_input, everett, everett_output
from stageid.hysteresis.preisach_identification import PreisachIdentifier, cell_regressors
from stageid.hysteresis.serialization import model_from_dict


def _random_model(seed, n=7):
    rng = np.random.default_rng(seed)
    return PreisachModel((-1.0, 1.0), rng.random(n * (n + 1) // 2), output_offset=rng.standard_normal())


def _walk(seed, n=400):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.standard_normal(n)) * 0.2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stack_kernel_equals_the_cell_area_twin(seed):
    m = _random_model(seed)
    u = _walk(seed, 150)
    # the twin integrates every cell's up part from the raw history (no stack, no Everett
    # table); same sums in another order: rounding only
    np.testing.assert_allclose(m(u), cells_reference(u, -1.0, m.step, m.weights) + m.output_offset, atol=1e-12)


def test_inputs_on_the_nodes_and_repeated_match_the_twin():
    m = _random_model(3, n=5)
    u = np.repeat(m.nodes, 2)[::-1].copy()  # exactly on every node, falling then rising, each twice
    u = np.r_[u, u[::-1], 5.0, -5.0, 0.3]  # and beyond both ends of the grid
    np.testing.assert_allclose(m(u), cells_reference(u, -1.0, m.step, m.weights) + m.output_offset, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 4])
def test_everett_differences_equal_the_kernel(seed):
    m = _random_model(seed)
    u = _walk(seed + 10)
    np.testing.assert_allclose(everett_output(m, u), m(u), atol=1e-12)


def test_everett_is_the_weight_of_the_triangle():
    m = _random_model(5, n=4)  # nodes -1, -0.5, 0, 0.5, 1
    W = m.weight_matrix()
    # alpha <= 0.5, beta >= -0.5: cells (1,1), (2,1), (2,2) whole
    assert everett(m, 0.5, -0.5) == pytest.approx(W[1, 1] + W[2, 1] + W[2, 2], abs=1e-15)
    # half of cell (3,1) along alpha, half of the diagonal cell 3
    assert everett(m, 0.75, -0.5) == pytest.approx(W[1, 1] + W[2, 1] + W[2, 2] + (W[3, 1] + W[3, 2] + W[3, 3]) / 2)
    # alpha <= 0.25, beta >= -0.75: half of the diagonals 0 and 2, half of (1, 0) and (2, 1),
    # a quarter of the square (2, 0) (alpha in [0, 0.25], beta in [-0.75, -0.5]), all of (1, 1)
    E = W[0, 0] / 2 + W[1, 0] / 2 + W[1, 1] + W[2, 0] / 4 + W[2, 1] / 2 + W[2, 2] / 2
    assert everett(m, 0.25, -0.75) == pytest.approx(E, abs=1e-15)
    assert everett(m, -1.0, -2.0) == 0.0


def test_output_is_continuous_piecewise_linear_in_the_input():
    m = PreisachModel((0.0, 2.0), [0.0, 1.0, 0.0])  # one square: alpha in [1, 2], beta in [0, 1]
    assert m(np.array([0.0, 1.0, 1.5, 2.0, 1.0, 0.5, 0.0])).tolist() == [0.0, 0.0, 0.5, 1.0, 1.0, 0.5, 0.0]
    # from the top down to 0.5 and back up: the lower half of the cell returns only above alpha 1
    y = m(np.array([2.0, 0.5, 1.0, 1.5, 2.0]))
    np.testing.assert_allclose(y, [1.0, 0.5, 0.5, 0.75, 1.0], atol=1e-15)


def test_state_resumes_the_run():
    m = _random_model(6)
    u = _walk(6)
    y, memory = m.run(u[:150])
    y2, _ = m.with_state(memory).run(u[150:])
    np.testing.assert_array_equal(np.r_[y, y2], m(u))


@pytest.mark.parametrize("centre", [-0.3, 0.0, 0.55])
def test_demagnetised_state_is_the_twin_after_the_demagnetising_input(centre):
    m = _random_model(9, n=4)
    d = demagnetizing_input(-1.0, 1.0, 4, centre)
    u = _walk(9, 60) * 0.5 + centre
    m0 = m.with_state(m.consistent_state(centre))
    ref = cells_reference(np.r_[d, u], -1.0, m.step, m.weights)[d.size :]
    np.testing.assert_allclose(m0(u), ref + m.output_offset, atol=1e-12)


def test_demagnetised_about_the_centre_of_a_symmetric_density_is_half_up():
    n = 6
    W = np.add.outer(np.arange(n), -np.arange(n)) + 1.0  # depends on alpha - beta only: symmetric
    m = PreisachModel((-1.0, 1.0), W[np.tril_indices(n)])
    total = float(m.weights.sum())
    half = m.with_state(m.consistent_state(0.0))(np.array([0.0]))[0]
    # the staircase straddles alpha + beta = 0; its corners cost at most a few 1e-3 of the total
    assert abs(half - total / 2) < 5e-3 * total


@pytest.mark.parametrize("kind, start", [("ascending", -1.0), ("descending", 1.0)])
def test_ascending_and_descending_states_start_from_an_end(kind, start):
    m = _random_model(11)
    u = _walk(11, 80) * 0.4
    m0 = m.with_state(m.consistent_state(u[0], kind))
    np.testing.assert_allclose(m0(u), m(np.r_[start, u])[1:], atol=1e-12)


def test_json_round_trip_is_byte_stable():
    from stageid.models.serialization import dumps

    m = _random_model(7)
    m = m.with_state(m.consistent_state(0.1))
    text = dumps(m.to_dict())
    back = model_from_dict(json.loads(text))
    assert isinstance(back, PreisachModel)
    assert dumps(back.to_dict()) == text
    np.testing.assert_array_equal(back(_walk(1)), m(_walk(1)))


def test_a_point_relay_file_is_refused_with_one_line():
    d = PreisachModel((0.0, 2.0), [0.0, 1.0, 0.0]).to_dict()
    del d["density"]
    with pytest.raises(ModelFormatError, match="density") as info:
        model_from_dict(d)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "field, value",
    [("weights", [1.0, True, 2.0]), ("n_levels", 3), ("state", [0.5, 1.5, 0.2]), ("input_range", [1.0, 0.0])],
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
    centres = true.nodes[:-1] + h / 2
    for i, a in enumerate(centres):
        for b in centres[: i + 1][::-1]:  # peak inside cell alpha_i, trough inside beta_j
            p, q = a + h / 4, b - h / 4
            legs += [np.linspace(-1.0, p, 30), np.linspace(p, q, 30), np.linspace(q, -1.0, 30)]
    u = np.concatenate(legs)
    m0 = true.with_state(true.consistent_state(u[0]))
    y = m0(u)
    fit = PreisachIdentifier(n_levels=n, smoothing=0.0, input_range=(-1.0, 1.0)).fit((u, y))
    # noise-free data on the model's own grid: the cell weights themselves come back
    np.testing.assert_allclose(fit.model.weights, true.weights, atol=1e-6)
    assert fit.max_error_percent[0] < 1e-6


def test_regressors_reproduce_the_model():
    m = _random_model(8)
    u = _walk(8)
    Phi = cell_regressors(u, m.input_range, m.n_levels)
    m0 = m.with_state(m.consistent_state(u[0]))
    np.testing.assert_allclose(Phi @ m.weights + m.output_offset, m0(u), atol=1e-12)


def test_grid_finer_than_the_data_is_one_data_error():
    u = np.r_[np.linspace(0, 1, 50), np.linspace(1, -1, 100)]  # one reversal only
    y = u**3
    with pytest.raises(DataError, match="finer than the records resolve") as info:
        PreisachIdentifier(n_levels=12).fit((u, y))
    assert "\n" not in str(info.value)
