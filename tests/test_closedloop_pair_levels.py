"""The work the closed-loop pairs take: the rest-level search ranks levels with the cheaper fit and
refits from its last fit; a coupling's first fit, which only gives its levels, is the cheaper one."""

from __future__ import annotations

from collections import Counter

import numpy as np

from _closedloop_plant2x2 import chirp_experiments
from stageid.closedloop import pem
from stageid.closedloop.loop_model import at_rest, group_by_reference, identify_pairs


def _counted(calls: Counter, name: str):
    def fit(r, y, dt):  # order 6 holds the lead-lag loop's dominant poles
        calls[name] += 1
        return pem(r, y, "oe", {"nb": 6, "nf": 6}, 1, dt)

    return fit


def test_levels_and_a_couplings_first_fit_come_from_the_cheaper_fit():
    exps = chirp_experiments((1, 2), duration=0.25)
    calls: Counter = Counter()
    full, cheap = _counted(calls, "full"), _counted(calls, "cheap")
    groups = at_rest(group_by_reference(exps), cheap)
    assert calls == {"cheap": 4}  # first sample and mean per reference; the passes refit from there
    calls.clear()
    _, models, fits, _ = identify_pairs(groups, full, cheap)
    # every pair's order selected on y - d; a diagonal's on y too, a coupling's first fit the cheaper
    assert calls == {"full": 6, "cheap": 2}
    assert np.diag(fits).min() > 99.0
    assert set(models) == {(0, 0), (0, 1), (1, 0), (1, 1)}
