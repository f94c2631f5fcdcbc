"""Step 2 of the stage identification is one problem with the hysteresis side plugged in.

:class:`StageProblem` alternates the weights and the dynamics ``G`` for whatever supplies the
columns the output is linear in: the PI operators, the Preisach cells, or (here) a plain gain,
whose alternation must recover a known ``G`` exactly from noise-free data.
"""

import numpy as np

from stageid.hysteresis.stage.dynamics import unit_gain_filter
from stageid.hysteresis.stage.pi_columns import PIColumns
from stageid.hysteresis.stage.preisach import PreisachColumns
from stageid.hysteresis.stage.problem import StageProblem

DT = 1e-3


class GainColumns:
    """A 'hysteresis' that is a gain: one column, the input; weights by least squares."""

    n_alternations = 4
    settle = 0.0
    max_rows = 40000

    def __init__(self, recs):
        self.recs = recs
        self.kinds = ["zero"] * len(recs)
        self.Z = [u[:, None] for u, _ in recs]
        self.live = np.array([0])

    def search_columns(self, cols, masks, stride):
        return cols

    def grid_starts(self, problem, cols, masks, order):
        return []

    def solve_weights(self, cols, masks, nc, stride):
        J = len(cols)
        X = np.vstack([np.hstack([c[m], np.eye(J)[[j] * int(m.sum())]]) for j, (c, m) in enumerate(zip(cols, masks))])
        t = np.concatenate([y[m] for (_, y), m in zip(self.recs, masks)])
        sol = np.linalg.lstsq(X, t, rcond=None)[0]
        return sol[: cols[0].shape[1]], sol[cols[0].shape[1] :]

    def hysteresis(self, w, c, offset, taus, dt, in_name, out_name):
        raise NotImplementedError  # not built here


def test_a_plugged_in_gain_recovers_the_dynamics_exactly():
    rng = np.random.default_rng(0)
    b, a = np.array([0.0, 0.3]), np.array([1.0, -0.7])  # unit DC gain, one-sample delay
    recs = []
    for offset in (2.0, -1.0):
        u = np.repeat(rng.uniform(-1.0, 1.0, 200), 20)
        recs.append((u, offset + unit_gain_filter(b, a, 3.0 * u[:, None])[:, 0]))
    problem = StageProblem(GainColumns(recs), DT)
    w, c, offsets, ba = problem.solve(1, (), [np.ones(u.size, bool) for u, _ in recs])
    # noise-free: the gain, the offsets and G's response to rounding of the alternation's fits
    assert c.size == 0
    np.testing.assert_allclose(w, [3.0], rtol=1e-8)
    np.testing.assert_allclose(offsets, [2.0, -1.0], atol=1e-8)
    z = np.exp(2j * np.pi * np.linspace(0.0, 0.5, 11))
    np.testing.assert_allclose(
        np.polyval(ba[0], z) / np.polyval(ba[1], z), np.polyval(b, z) / np.polyval(a, z), atol=1e-8
    )


def test_pi_and_preisach_sides_set_their_own_alternation():
    from stageid.hysteresis.identify.pi import PIIdentifier
    from stageid.hysteresis.identify.preisach import PreisachIdentifier
    from stageid.plants.piezo_actuator import EXPERIMENTS

    exp = EXPERIMENTS["decaying-triangle"](seed=0)
    recs = [(exp.u[:, 0], exp.y[:, 0])]
    pi = StageProblem(PIColumns(PIIdentifier("pi", n_operators=6).fit(exp).model, recs, ["zero"]), exp.dt)
    preisach = StageProblem(
        PreisachColumns(PreisachIdentifier(n_levels=6).fit(exp).model, recs, ["zero"], 1e-4), exp.dt
    )
    # the PI fit runs all its rounds; the Preisach one, whose searches see a projection, until it settles
    assert (pi.n_alternations, pi.settle) == (4, 0.0)
    assert (preisach.n_alternations, preisach.settle) == (30, 1e-4)
    assert preisach.stride >= pi.stride  # fewer least-squares rows for the many cells
    for problem in (pi, preisach):
        w, _, _, _ = problem.solve(0, (), [np.ones(exp.u.shape[0], bool)])
        model = problem.build(w, np.zeros(0), 0.0, (), None, "u", "y")
        assert model.hysteresis.kind == ("pi" if problem is pi else "preisach")
