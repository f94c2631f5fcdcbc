"""Tests written to kill survivors of the ``frf`` mutation group (tests/MUTATION.md)."""

import numpy as np
import pytest

from stageid.data import Experiment
from stageid.frf import periodic_frf
from stageid.models import StateSpaceModel
from stageid.signals import multisine

DT = 1e-3


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_periodic_excited_lines_do_not_depend_on_the_input_units(scale):
    # a multisine on lines 1-400 of a 1000-sample period: the same 400 lines and the same response
    # whether the input is in metres or micrometres (lines are excited relative to the strongest)
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[1.0, 0.5]], [[0.0]], dt=DT)
    u = np.asarray(multisine(1000 * 24, DT, 1.0, 400.0, seed=0, n_periods=24)).reshape(-1, 1)
    y = g.simulate(u)
    u, y = scale * u[-4000:], y[-4000:]
    frd = periodic_frf(Experiment(u, y, DT), periods=4, transient_periods=0)
    assert frd.n_freqs == 400
    G = g.frequency_response(frd.freqs) / scale
    assert np.max(np.abs(frd.response - G)) <= 1e-9 * np.max(np.abs(G))
