"""Minimal realisation of continuous plants whose entries carry large polynomial coefficients."""

from __future__ import annotations

import numpy as np

from stageid.models import TransferMatrix


def test_poles_of_a_plant_with_a_high_frequency_coupling_are_all_kept():
    # the closed-loop paper's structure: unstable [0, 2] diagonals and third-order couplings with a
    # lightly damped mode at 2000 rad/s (coefficients up to 1.2e9); the norm-relative threshold
    # on the unbalanced companion blocks called every state unobservable (no poles at all)
    w, zeta = 2000.0, 0.01
    coupling = np.polymul([1.0, 300.0], [1.0, 2 * zeta * w, w**2])
    num = [[[3.0], [40.0]], [[25.0], [2.0]]]
    den = [[np.polymul([1, -50.0], [1, 80.0]), coupling], [coupling, np.polymul([1, -70.0], [1, 90.0])]]
    plant = TransferMatrix(num, den, None)
    poles = plant.poles()
    assert poles.size == 10  # two second-order diagonals, two third-order couplings: no shared pole
    unstable = np.sort(poles[poles.real > 0].real)
    np.testing.assert_allclose(unstable, [50.0, 70.0], rtol=1e-6)
    # the realisation is the plant: the same response as the entries
    f = np.geomspace(1.0, 1000.0, 50)
    ss = plant.to_statespace()
    np.testing.assert_allclose(ss.frequency_response(f), plant.frequency_response(f), rtol=1e-6)
