"""Continuous-cell Preisach model: stack kernel vs cell-area twin vs Everett sums, states, JSON, identification."""

import json

import numpy as np
import pytest

from stageid import DataError, ModelFormatError
from stageid.hysteresis.identify.preisach import PreisachIdentifier, cell_regressors
from stageid.hysteresis.kernels.preisach import cells_reference
from stageid.hysteresis.models.preisach import PreisachModel, demagnetizing_input, everett, everett_output
from stageid.hysteresis.models.serialization import model_from_dict


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


def test_one_reversal_on_a_fine_grid_is_filled_not_refused():
    u = np.r_[np.linspace(0, 1, 50), np.linspace(1, -1, 100)]  # one reversal only
    y = u**3
    fit = PreisachIdentifier(n_levels=12).fit((u, y))
    # one descending branch determines the column sums only: most cells come from the prior
    assert fit.filled_cells > 30
    assert f"filled {fit.filled_cells} cells" in fit.summary() and "\n" not in fit.summary()
    assert np.all(fit.model.weights >= 0) and fit.rms_error_percent[0] < 1.0


def test_a_constant_input_determines_nothing_and_is_one_data_error():
    u = np.full(200, 0.3)
    y = np.sin(np.arange(200) / 7.0)
    with pytest.raises(DataError, match="constant input") as info:
        PreisachIdentifier(n_levels=8).fit((u, y))
    assert "\n" not in str(info.value)


def _experiment(name):
    from stageid.plants.piezo_actuator import EXPERIMENTS

    e = EXPERIMENTS[name](seed=0)
    return e.u[:, 0], e.y[:, 0]


def test_twenty_levels_on_a_decaying_sine_fit_and_report_the_filled_cells():
    # the nested minor loops of one decaying sine leave part of a 20-level grid without a
    # reversal pair (the grid was refused before the prior): the prior fills those cells
    u, y = _experiment("decaying-sine")
    fit = PreisachIdentifier(n_levels=20).fit((u, y))
    assert 0 < fit.filled_cells < 210
    assert f"filled {fit.filled_cells} cells the records leave undetermined" in fit.summary()
    # the actuator is not a Preisach model on this grid; 0.5 % rms is the fit on its own record
    assert fit.rms_error_percent[0] < 0.5
    assert np.all(fit.model.weights >= 0)


def test_cells_the_data_determine_keep_the_fit_without_the_prior_floor():
    from scipy.optimize import nnls

    from stageid.hysteresis.identify.preisach import second_differences

    u, y = _experiment("decaying-triangle")  # every cell of a 20-level grid has a reversal pair
    lo, hi, n = float(u.min()), float(u.max()), 20
    fit = PreisachIdentifier(n_levels=n).fit((u, y))
    assert fit.filled_cells == 0
    # the weights as the penalised NNLS gave them before the prior took over undetermined cells
    Phi = cell_regressors(u, (lo, hi), n)
    A, b = Phi - Phi.mean(axis=0), y - y.mean()
    lam = 1e-4 * float(np.mean(np.sum(A**2, axis=0)))
    D = second_differences(n)
    w, _ = nnls(np.vstack([A, np.sqrt(lam) * D]), np.r_[b, np.zeros(D.shape[0])], maxiter=50 * A.shape[1])
    # noise-free record, same cost: only the solver's rounding (1e-9 of the largest weight) differs
    np.testing.assert_allclose(fit.model.weights, w, rtol=0, atol=1e-9 * w.max())
    # and without any smoothing beyond the floor the determined cells move by far less than the
    # penalty's own bias (the floor is 1e8 times smaller than the default smoothing)
    bare = PreisachIdentifier(n_levels=n, smoothing=0.0).fit((u, y))
    assert bare.filled_cells == 0
    assert bare.rms_error_percent[0] <= fit.rms_error_percent[0] + 1e-6


def test_cells_without_reversal_pairs_interpolate_their_neighbours():
    n = 10
    A, B = np.tril_indices(n)
    h = 2.0 / n
    ca, cb = -1 + (A + 0.5) * h, -1 + (B + 0.5) * h
    # a smooth density (Gaussian across the diagonal, tilted), so neighbours predict a cell
    true = PreisachModel((-1.0, 1.0), np.exp(-(((ca - cb) / 0.8) ** 2)) * (1 + 0.3 * (ca + cb)) * h * h)
    centres = true.nodes[:-1] + h / 2
    legs = [np.linspace(0.0, -1.0, 20)]
    for i, a in enumerate(centres):
        if i in (4, 5):  # no reversal peak inside alpha rows 4 and 5: those cells are not seen
            continue
        for b in centres[: i + 1][::-1]:
            p, q = a + h / 4, b - h / 4
            legs += [np.linspace(-1.0, p, 30), np.linspace(p, q, 30), np.linspace(q, -1.0, 30)]
    u = np.concatenate(legs)
    y = true.with_state(true.consistent_state(u[0]))(u)
    fit = PreisachIdentifier(n_levels=n, input_range=(-1.0, 1.0)).fit((u, y))
    assert 5 <= fit.filled_cells <= 11  # the 11 cells of rows 4 and 5, less the ones sums pin
    W, Wt = fit.model.weight_matrix(), true.weight_matrix()
    # the filled rows: near the smooth truth (3 % of the largest weight), and between their
    # determined neighbours in rows 3 and 6 (interpolated, not extrapolated; 0.5 % slack)
    for i in (4, 5):
        np.testing.assert_allclose(W[i, : i + 1], Wt[i, : i + 1], atol=0.03 * Wt.max())
        low, high = np.minimum(W[3, :4], W[6, :4]), np.maximum(W[3, :4], W[6, :4])  # columns both rows hold
        assert np.all(W[i, :4] >= low - 0.005 * Wt.max()) and np.all(W[i, :4] <= high + 0.005 * Wt.max())
