"""The disturbance modes proposed for the held-out test: the chosen fit's residual first, the
residuals of the selection's held-out fits when that one shows none."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from scipy.signal import lfilter

from stageid.hysteresis.stage.disturbance_modes import MAX_MODES, DisturbanceMode, disturbance_modes
from stageid.hysteresis.stage.dynamics import zoh_resonance
from stageid.hysteresis.stage.mode_proposals import fold_residuals, proposed_modes, strongest_distinct

DT = 1e-4


def _drive(f, seconds):
    """A decaying sine of ``f`` Hz (the FORC records' kind of drive)."""
    n = int(round(seconds / DT))
    return 10.0 * np.exp(-1.5 * np.arange(n) / n) * np.sin(2 * np.pi * f * DT * np.arange(n))


class _Problem:
    """The parts of a StageProblem that the proposals read: records, the chosen fit's residuals
    and, per order, the held-out folds (each record left out in turn)."""

    def __init__(self, chosen, per_order, drives):
        self.recs = [(u, 10.0 * np.sin(np.linspace(0.0, 3.0, u.size))) for u in drives]
        self.dt = DT
        self.chosen = chosen
        self.per_order = per_order
        self.asked = []

    def residuals(self, model, offsets):
        return self.chosen

    def held_out_residuals(self, order, taus):
        self.asked.append((order, tuple(taus)))
        e = self.per_order[order]
        return [([e[1]], [(e[0], 1.0)]), ([e[0]], [(e[1], 1.0)])]


def _white_and_rung(seed):
    rng = np.random.default_rng(seed)
    drives = [_drive(20.0, 1.5), _drive(100.0, 0.6)]
    white = [0.05 * rng.standard_normal(u.size) for u in drives]
    b, a = zoh_resonance(700.0, 0.015, DT)
    rung = [lfilter(b, a, rng.standard_normal(u.size)) + 0.05 * rng.standard_normal(u.size) for u in drives]
    return drives, white, rung


def test_a_mode_hidden_in_the_chosen_fit_is_proposed_from_the_held_out_fits():
    """The chosen fit's residual shows no mode (white); the held-out fits of order 1 show a
    700 Hz ring: it is proposed (the detection on the chosen residual alone finds nothing)."""
    drives, white, rung = _white_and_rung(3)
    problem = _Problem(white, {0: white, 1: rung}, drives)
    model = SimpleNamespace(dynamics=None)
    assert disturbance_modes(white, drives, DT, None, 10.0) == ()
    (mode,) = proposed_modes(problem, model, np.zeros(2), (0, 1), (0.05,))
    assert abs(mode.frequency_hz - 700.0) < 14.0 and 0.01 < mode.damping < 0.0225
    assert problem.asked == [(0, (0.05,)), (1, (0.05,))]


def test_the_chosen_fits_modes_are_the_proposal_and_nothing_else_is_fitted():
    drives, white, rung = _white_and_rung(4)
    problem = _Problem(rung, {0: white, 1: white}, drives)
    (mode,) = proposed_modes(problem, SimpleNamespace(dynamics=None), np.zeros(2), (0, 1), ())
    assert abs(mode.frequency_hz - 700.0) < 14.0
    assert problem.asked == []


def test_residuals_at_rounding_level_propose_nothing_from_any_fit():
    drives, _, rung = _white_and_rung(5)
    tiny = [1e-15 * r for r in rung]
    problem = _Problem(tiny, {0: tiny, 1: tiny}, drives)
    assert proposed_modes(problem, SimpleNamespace(dynamics=None), np.zeros(2), (0, 1), ()) == ()
    assert len(problem.asked) == 2


def test_one_mode_seen_by_several_fits_is_proposed_once_at_its_strongest():
    a = DisturbanceMode(745.0, 0.03, 8.0)
    b = DisturbanceMode(748.0, 0.02, 13.0)  # within SEPARATION half-widths of a
    c = DisturbanceMode(1500.0, 0.02, 7.0)
    d = DisturbanceMode(2500.0, 0.02, 6.5)
    assert strongest_distinct([a, b]) == [b]
    assert strongest_distinct([a, c, b, d]) == [b, c, d][:MAX_MODES]


def test_fold_residuals_are_in_record_order():
    r = [np.full(3, float(k)) for k in range(3)]
    folds = [([r[1], r[2]], [(r[0], 1.0)]), ([r[0], r[2]], [(r[1], 1.0)]), ([r[0], r[1]], [(r[2], 1.0)])]
    for fold in fold_residuals(folds):
        assert [float(e[0]) for e in fold] == [0.0, 1.0, 2.0]
    # a single record: its fitted first part and its held-out rest, joined
    (single,) = fold_residuals([([np.zeros(6)], [(np.ones(4), 1.0)])])
    assert len(single) == 1 and single[0].size == 10 and single[0][-1] == 1.0
    assert fold_residuals(None) == []
