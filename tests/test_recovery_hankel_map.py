"""Seeded draws of the Hankel-MAP recovery benchmark (``benchmarks/recovery/rec_hankel_map.py``)
that once failed or stayed far from the output-error optimum of their class, each run as the
benchmark runs it (records written with a logger's time column, fitted through the command
line with its defaults), and the output-error refinement's derivatives."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks" / "recovery"))

import rec_hankel_map  # noqa: E402
from common import draw_noise  # noqa: E402


@pytest.mark.parametrize(
    ("seed", "error_before", "ratio_before"),
    [
        (3, 2.49, 1.79),  # 3 inputs x 1 output, order 3, one record of 2.6k samples: a 13.5 Hz mode ringing longer
        # than the record, placed by the horizon-30 eq. 9 model 1e-4 of its frequency off
        (19, 5.1, 8.23),  # 1x1, order 7, one record: modes at 31.1 and 32.3 Hz, order 11 chosen
        (1, 0.715, 5.07),  # 3x1, order 4: recovered, but five times the output-error optimum's cost
    ],
)
def test_draw_reaches_the_output_error_optimum(tmp_path, seed, error_before, ratio_before):
    row = rec_hankel_map.case(seed, tmp_path, draw_noise(seed))
    assert not row.failed
    assert row.recovered, f"error {row.error:.3g} % of peak (before the refinement {error_before} %)"
    # the reference minimises the same cost over C, D from the truth: within 2 % of it (before: ratio_before)
    assert row.cost_ratio < 1.02


def test_output_error_refinement_is_what_moves_the_draw(tmp_path):
    # seed 3 without the refinement: the realisation alone misses (2.49 % of peak, criterion 2 %)
    from stageid.data import Experiment
    from stageid.subspace import HankelMAP

    rng = np.random.default_rng([3, 101])
    (A, B, C, D), freqs = rec_hankel_map.true_system(rng)
    u = rec_hankel_map.inputs(np.random.default_rng(7), 2600, B.shape[1])
    y0 = rec_hankel_map.simulate(A, B, C, D, u)
    y = y0 + 0.009 * y0.std(0) * np.random.default_rng(8).standard_normal(y0.shape)
    band = np.linspace(freqs[0] / 10, 1.5 * freqs[-1], 400)
    truth = rec_hankel_map.response(A, B, C, D, band)

    def error(**kw):
        res = HankelMAP(order=3, **kw).fit(Experiment(u, y, 1e-3))
        return 100 * np.abs(res.model.frequency_response(band) - truth).max() / np.abs(truth).max()

    assert error(output_error=False) > 2.0 * error()
    assert error() < 1.0


@pytest.mark.parametrize("feedthrough", [False, True])
def test_output_error_gradient_matches_finite_differences(feedthrough):
    # two pole pairs and a real pole, two records of several blocks, fitted initial states and offsets
    from stageid.subspace.realisation import output_error as oe

    rng = np.random.default_rng(1)
    A = np.zeros((5, 5))
    A[:2, :2] = [[0.95, -0.2], [0.2, 0.95]]
    A[2:4, 2:4] = [[0.8, -0.3], [0.3, 0.8]]
    A[4, 4] = 0.7
    B, C, D = rng.standard_normal((5, 2)), rng.standard_normal((3, 5)), rng.standard_normal((3, 2))
    records = [(rng.standard_normal((300, 2)), rng.standard_normal((300, 3))) for _ in range(2)]
    w = np.array([1.0, 0.5, 0.7])
    model = oe.Modal.from_abcd(A, B, C, D)
    starts = [
        (rng.standard_normal(3) + 1j * np.array([1.0, 1.0, 0.0]) * rng.standard_normal(3), rng.standard_normal(3))
    ]
    starts.append((np.zeros(3, dtype=complex), np.zeros(3)))
    n_shared = model.vector(feedthrough).size
    problem = oe.OutputErrorProblem(tuple(records), w, feedthrough)
    _, _, g = oe.weighted_pass(model, starts, problem, block=128)

    def cost(step):
        moved = model.moved(step[:n_shared], feedthrough)
        return oe.weighted_pass(moved, oe.moved_starts(model, starts, step[n_shared:]), problem, jacobian=False)[0]

    eps, numeric = 1e-6, np.zeros(g.size)
    for i in range(g.size):
        e = np.zeros(g.size)
        e[i] = eps
        numeric[i] = (cost(e) - cost(-e)) / (2 * eps)
    # the cost is |r|^2 with r = y - y_hat, so its gradient is -2 J^T r; 1e-6 of the largest: central differences
    assert np.max(np.abs(numeric + 2 * g)) < 1e-6 * np.max(np.abs(numeric))


def test_modal_form_keeps_the_response():
    from stageid.models import StateSpaceModel
    from stageid.subspace.realisation.output_error import Modal

    rng = np.random.default_rng(2)
    A = rng.standard_normal((5, 5)) * 0.3
    B, C, D = rng.standard_normal((5, 2)), rng.standard_normal((2, 5)), rng.standard_normal((2, 2))
    f = np.linspace(0.5, 45.0, 9)
    before = StateSpaceModel(A, B, C, D, 0.01).frequency_response(f)
    after = StateSpaceModel(*Modal.from_abcd(A, B, C, D).to_abcd(), 0.01).frequency_response(f)
    assert np.max(np.abs(after - before)) < 1e-10 * np.max(np.abs(before))


def test_refinement_too_costly_is_not_run_and_the_result_says_so(monkeypatch):
    from stageid.data import Experiment
    from stageid.subspace import HankelMAP, channel_fit

    rng = np.random.default_rng(4)
    u = rng.standard_normal((1500, 1))
    y = np.convolve(u[:, 0], 0.9 ** np.arange(30))[:1500, None] * [1.0, 0.5]
    exp = Experiment(u, y + 1e-3 * rng.standard_normal(y.shape), 1e-3)
    monkeypatch.setattr(channel_fit, "OE_MAX_WORK", 0.0)
    res = HankelMAP(order=2).fit(exp)
    assert any("output-error refinement was not run" in w for w in res.diagnostics["warnings"])
    plain = HankelMAP(order=2, output_error=False).fit(exp)
    assert np.allclose(res.model.frequency_response([10.0, 50.0]), plain.model.frequency_response([10.0, 50.0]))


@pytest.mark.xfail(
    strict=True,
    reason="two modes 2 % apart merged by the realisation at every order the rule scores "
    "(benchmarks/RESULTS-recovery.md, Hankel-MAP: seed 54 of 60)",
)
def test_modes_two_percent_apart_are_separated(tmp_path):
    row = rec_hankel_map.case(54, tmp_path, draw_noise(54))  # 2 inputs x 1 output, order 8, three records
    assert row.recovered, f"error {row.error:.3g} % of peak, {row.detail}"
