"""Tests written to kill survivors of the ``stage`` mutation group (tests/MUTATION.md)."""

from stageid.hysteresis.stage.selection import AUTO_TOLERANCE, choose_candidate


class _Scores:
    """Stands in for a stage problem: a held-out score per (order, creep time constants)."""

    def __init__(self, scores):
        self.scores = scores

    def held_out_score(self, order, taus):
        return self.scores[(order, tuple(taus))]


def test_the_simplest_candidate_within_tolerance_and_ties_go_to_the_lower_order():
    best = 1.0
    within = best * (1 + AUTO_TOLERANCE) + 0.5e-3  # inside the tolerance, above the best
    scores = {(1, ()): 10.0, (2, ()): best, (1, (0.1,)): within, (2, (0.1,)): best}
    order, taus, held_out = choose_candidate(_Scores(scores), (1, 2), ((), (0.1,)))
    # (2, none) and (1, one lag) are equally simple (2 states): the lower dynamics order wins,
    # whatever their scores within the tolerance
    assert (order, tuple(taus)) == (1, (0.1,))
    assert sorted((n, tuple(t), s) for n, t, s in held_out) == sorted((n, t, s) for (n, t), s in scores.items())
    # outside the tolerance the simpler candidate is passed over
    scores[(1, (0.1,))] = best * (1 + AUTO_TOLERANCE) + 2e-3
    order, taus, _ = choose_candidate(_Scores(scores), (1, 2), ((), (0.1,)))
    assert (order, tuple(taus)) == (2, ())


def test_a_single_candidate_is_taken_without_scoring():
    order, taus, held_out = choose_candidate(None, (3,), ((0.2,),))
    assert (order, taus, held_out) == (3, (0.2,), [])
