"""Seeded draws of the closed-loop recovery benchmark (``benchmarks/recovery/loop_draws.py``) that
once failed: random open-loop-unstable stages of the paper's class in a loop with a lead-lag per
axis, records written with a logger's time column and read back as the command reads them."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks" / "recovery"))

import loop_draws  # noqa: E402
from common import draw_noise  # noqa: E402


def _draw(tmp_path, seed: int, salt: int, noise: float):
    """(true plant, controller, experiments as read from the written files)."""
    from stageid.data import as_experiments, read_table

    rng = np.random.default_rng([seed, salt])
    plant, K, _ = loop_draws.draw_loop(rng)
    paths, *_ = loop_draws.write_experiments(rng, plant, K, noise, tmp_path)
    n = plant.n_outputs
    refs, outs = [f"r{i + 1}" for i in range(n)], [f"y{i + 1}" for i in range(n)]
    exps = as_experiments([read_table(p).experiment(inputs=refs, outputs=outs, name=str(p)) for p in paths])
    return plant, K, exps


@pytest.mark.parametrize(
    ("seed", "salt"),
    [
        (1, 202),  # 2x2, multisine: the level search stayed at the first sample, T off by 130 % of its peak
        (4, 202),  # 2x2, multisine: 33 %
    ],
)
def test_multisine_about_the_rest_level_gives_the_closed_loop(tmp_path, seed, salt):
    # the loop rested at the multisine's mean before the record; its first sample is far from it
    from stageid.closedloop import select_order
    from stageid.closedloop.loop_model import at_rest, group_by_reference, identify_pairs

    def fit_pair(r, y, dt):  # the estimator's default: output error, BIC over orders 2-16
        return select_order(r, y, "oe", range(2, 17), 1, dt)[0]

    plant, K, exps = _draw(tmp_path, seed, salt, 0.003)
    T, _, fits, _ = identify_pairs(at_rest(group_by_reference(exps), fit_pair), fit_pair)
    f = np.geomspace(5.0, 1000.0, 200)
    truth = loop_draws.closed_loop_response(plant, K, f)
    error = np.abs(T.frequency_response(f) - truth).max() / np.abs(truth).max()
    assert error < 0.02  # the benchmark's criterion (measured 0.1-2.2 % after, 33-130 % before)
    assert np.diag(fits).min() > 99.0


@pytest.mark.parametrize(
    ("seed", "noise"),
    [
        # 2x2, multisine: refused by the paper-structure check ("y2<-u2 misses [0, 2] by 9.0 %"),
        # its largest misfit at a coupling resonance the free pairs under-model
        (3, 0.0092),
        # 2x2, chirp from DC: the loop 3.8x the noise floor on the records, a constant from the
        # outputs' first samples
        (2, 0.0065),
    ],
)
def test_pem_draw_is_recovered_through_the_command(tmp_path, seed, noise):
    import rec_pem

    row = rec_pem.case(seed, tmp_path, noise, salt=303)  # the PEM case's own stream of draws then
    assert row.failed == "" and row.recovered, row
    assert row.cost_ratio <= 1.1  # the case's criterion (measured 1.086 and 1.010)


@pytest.mark.study
@pytest.mark.xfail(
    strict=True,
    reason="3x3 multisine, 0.32 % noise: the diagonal pairs refitted through the sensitivity noise model "
    "leave the loop's output-error cost 1.126x the true loop's (1.012x with output error alone), over "
    "the case's 1.1; its response error 0.41 % of peak",
)
def test_pem_draw_keeps_its_output_error_cost_under_the_noise_model(tmp_path):
    import rec_pem

    row = rec_pem.case(24, tmp_path, draw_noise(24))
    assert row.failed == "" and row.recovered, row


def test_lightly_damped_coupling_is_reduced_from_a_weighted_start(tmp_path):
    # 2x2, multisine: a [1, 3] coupling reduced from Levy's start alone missed its entry by 99 % of
    # the entry's peak; with the Sanathanan-Koerner passes 5.8 %. With the pairs at the loop's order
    # the deduction then gave two spurious unstable poles (a coupling mode at 236 Hz pushed across
    # the unit circle, a real one at 9.7 rad/s) that the (1, 0) coupling kept: 100 % off. Weighted by
    # the deduction's reliability, the stable coupling is preferred and follows the plant (3 %).
    import rec_closedloop

    row = rec_closedloop.case(7, tmp_path, 0.0151)
    assert row.failed == "", row
    assert row.error <= 10.0  # the case's band criterion, % of each entry's peak


@pytest.mark.parametrize(
    ("seed", "noise"),
    [
        # 2x2, multisine: refused, "singular at 0 Hz" (M (I - T) at 7.8e-7 of the controller's gain,
        # the rule's limit 1e-6), at a line below the records' resolution where T is extrapolated
        (4, 0.0038),
        # 2x2, multisine: coupling (1, 0) reduced 12 % off its peak from a deduced response within
        # 1.9 %: the plain relative fit followed the deduced response's error at 20 Hz (389 %)
        (11, 0.0078),
    ],
)
def test_closed_loop_draw_is_recovered_through_the_command(tmp_path, seed, noise):
    import rec_closedloop

    row = rec_closedloop.case(seed, tmp_path, noise)
    assert row.failed == "" and row.recovered, row  # unstable poles within 2 %, band error <= 10 %


def test_diagonal_pairs_reach_the_noise_floor(tmp_path):
    # PEM seed 5 (2x2, chirp, 0.96 % noise): the order screen ranked order 6 first, whose fit
    # stayed 1.33x the noise floor on both diagonal pairs; orders 12-16 reach it (0.995-0.997)
    from stageid.closedloop import ClosedLoopIdentification
    from stageid.closedloop.validation import simulate_closed_loop
    from stageid.data import as_experiments, read_table

    rng = np.random.default_rng([5, 303])
    plant, K, _ = loop_draws.draw_loop(rng)
    paths, records, *_ = loop_draws.write_experiments(rng, plant, K, 0.0096, tmp_path)
    names = {"inputs": ["r1", "r2"], "outputs": ["y1", "y2"]}
    exps = as_experiments([read_table(p).experiment(**names, name=str(p)) for p in paths])
    T = ClosedLoopIdentification(K, covariance="none").fit(exps).closed_loop
    for j, (R, y) in enumerate(records):
        floor = np.sum((y - simulate_closed_loop(plant, K, R, loop_draws.DT)[0])[:, j] ** 2)
        assert np.sum((y - T.simulate(R))[:, j] ** 2) < 1.05 * floor  # the benchmark bounds the loop's at 1.1


def _pair_cost(model, records, y_true, i: int, j: int) -> tuple[float, float]:
    """(the pair's summed squared output error on the records exciting ``j``, the truth's)."""
    cost = floor = 0.0
    for (R, y), yt in zip(records, y_true):
        if np.any(R[:, j]):
            cost += float(np.sum((y[:, i] - model.simulate(R[:, j])) ** 2))
            floor += float(np.sum((y[:, i] - yt[:, i]) ** 2))
    return cost, floor


@pytest.mark.study
@pytest.mark.parametrize(
    ("seed", "salt", "pair", "bound"),
    [
        # PEM seed 4 (3x3, chirp, 0.38 %): the coupling T_10, its order selected on outputs still
        # carrying the first sample's noise as an offset, stayed at 2.0x the noise floor (order 30);
        # selected again on the level-corrected outputs 0.95x
        (4, 303, (1, 0), 1.05),
        # PEM seed 9 (3x3, chirp, 1.03 %): T_00 at 1.23x from the linear starts and the climb, two
        # lightly damped coupling modes left out (residual peaks at 195 and 88 Hz); with both added 0.97x
        (9, 303, (0, 0), 1.05),
        # closed-loop seed 2 (3x3, chirp, 0.65 %): T_22 at 1.26x, the mode at 102 Hz left out (1.9 %
        # off there), which put the axis's unstable pole 5.5 % off; restarted with it added 0.99x
        (2, 202, (2, 2), 1.05),
        # PEM seed 12 (3x3, multisine, 0.13 %): T_00 1.08x after its first fit, 1.46x after the order
        # selected again and the refit, which was kept; the fit with the lowest level loss is kept now
        (12, 303, (0, 0), 1.1),  # the benchmark's bound on the loop's
    ],
)
def test_pair_of_a_3x3_loop_reaches_the_noise_floor(tmp_path, seed, salt, pair, bound):
    from stageid.closedloop import select_order
    from stageid.closedloop.loop_model import at_rest, fit_with_levels, group_by_reference, remembered
    from stageid.closedloop.validation import simulate_closed_loop
    from stageid.data import as_experiments, read_table

    rng = np.random.default_rng([seed, salt])
    plant, K, _ = loop_draws.draw_loop(rng)
    paths, records, *_ = loop_draws.write_experiments(rng, plant, K, draw_noise(seed), tmp_path)
    names = {"inputs": ["r1", "r2", "r3"], "outputs": ["y1", "y2", "y3"]}
    exps = as_experiments([read_table(p).experiment(**names, name=str(p)) for p in paths])

    def fit_pair(r, y, dt):  # the estimator's default for a 3x3 loop: orders 2 to its bound 30, plus 2
        return select_order(r, y, "oe", range(2, 33), 1, dt, refine_largest=True)[0]

    fit_pair = remembered(fit_pair)
    i, j = pair
    group = at_rest({j: group_by_reference(exps)[j]}, fit_pair)[j]
    m, _ = fit_with_levels([e.u[:, j] for e in group], [e.y[:, i] for e in group], exps[0].dt, fit_pair)
    y_true = [simulate_closed_loop(plant, K, R, loop_draws.DT)[0] for R, _ in records]
    cost, floor = _pair_cost(m, records, y_true, i, j)
    assert cost < bound * floor  # measured 0.95, 0.97, 0.99 and 1.08


@pytest.mark.parametrize(
    "seed",
    [
        # 2x2, chirp, 1.24 %: the diagonal pairs refitted through the noise model at the order the
        # output error selected (3 for T_00) put an unstable pole 14.7 % off (72.16 for 84.55 rad/s);
        # with the order selected again on the filtered records 0.19 %
        14,
        # 3x3, chirp, 0.92 % and 0.90 %: output-error pairs put an axis's unstable pole 3.68 % and
        # 3.42 % off (T_22 of seed 13 1.8e-3 off at 1 Hz where |1 - T_22| is 1.7e-3); now 1.87 % and 0.14 %
        pytest.param(3, marks=pytest.mark.study),
        pytest.param(13, marks=pytest.mark.study),
    ],
)
def test_unstable_pole_is_placed_by_the_pairs_below_the_crossover(tmp_path, seed):
    import rec_closedloop

    row = rec_closedloop.case(seed, tmp_path, draw_noise(seed))
    assert row.failed == "" and row.recovered, row  # unstable poles within 2 %, band error <= 10 %
