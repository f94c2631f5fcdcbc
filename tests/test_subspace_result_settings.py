"""A HankelMAP result keeps the settings it was fitted with: changing the estimator afterwards
changes neither the result nor what its ``update`` does."""

from __future__ import annotations

import numpy as np

from _subspace_systems import band_limited, random_stage, record
from stageid.subspace import HankelMAP


def test_update_uses_the_settings_of_the_fit_not_the_live_estimator():
    g = random_stage(7, m=1, q=1, modes=1)
    e1 = record(g, band_limited(6000, 1, g.dt, 1), 0.01, 1, names=False)
    e2 = record(g, band_limited(6000, 1, g.dt, 2), 0.01, 2, names=False)
    est = HankelMAP(horizon=30, order=2)
    res = est.fit(e1)
    expected = res.update(e2)
    est.order, est.forgetting = 4, 0.9  # would give a 4-state model and discount the first record
    assert res.estimator is not est and res.estimator.order == 2 and res.estimator.forgetting == 1.0
    updated = res.update(e2)
    assert updated.model.n_states == 2
    # same settings, same data: the same posterior to rounding
    np.testing.assert_allclose(updated.posterior.theta, expected.posterior.theta, rtol=0, atol=1e-12)


def test_clone_copies_the_settings():
    est = HankelMAP(horizon=30, order=[2, 3])
    twin = est.clone()
    assert twin is not est and twin.get_params() == est.get_params()
    twin.order.append(4)  # a list setting is copied, not shared
    assert est.order == [2, 3]
