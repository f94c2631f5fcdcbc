"""The maglev reference stage (Shakir & Kim eq. 22-24), our controller and the experiment simulator."""

from __future__ import annotations

import numpy as np
import pytest

from stageid.models import feedback
from stageid.plants import maglev, plant_module


def test_registered() -> None:
    assert plant_module("maglev") is maglev
    assert set(maglev.EXPERIMENTS) == {"chirp-x", "chirp-y", "chirp-phi"}


def test_dc_gains_follow_the_paper() -> None:
    g = maglev.model().dc_gain()
    # numbers computed by hand from eq. 22a, 23a, 24a, 22b, 24c
    assert g[0, 0] == pytest.approx(3.1845 / (-54.62 * 76.91), rel=1e-12)
    assert g[1, 1] == pytest.approx(3.1623 / (-82.21 * 76.91), rel=1e-12)
    assert g[2, 2] == pytest.approx(1530.1985 / (-86.73 * 76.91), rel=1e-12)
    assert g[1, 0] == pytest.approx(42.4017 / (13.83 * 1.98e6), rel=1e-12)  # G_xy: x -> y
    assert g[1, 2] == pytest.approx(0.9065 / (76.91 * 315.60), rel=1e-12)  # G_phiy: phi -> y
    assert g[2, 0] == pytest.approx(0.4266 * -6977.0 / (9.74 * 1.17e6), rel=1e-12)  # G_xphi, mirrored pole


def test_unstable_poles() -> None:
    p = maglev.model().to_statespace(minimal=False).poles()
    np.testing.assert_allclose(np.sort(p[p.real > 0].real), [54.62, 82.21, 86.73], rtol=1e-9)
    pp = maglev.model(published=True).to_statespace(minimal=False).poles()
    np.testing.assert_allclose(np.sort(pp[pp.real > 0].real), [9.74, 54.62, 82.21, 86.73], rtol=1e-9)


def test_controller_structure_and_crossover() -> None:
    Kc = maglev.controller_continuous()
    G = maglev.model()
    L = (
        G.frequency_response([maglev.CROSSOVER_HZ])[0]
        * np.diag(Kc.frequency_response([maglev.CROSSOVER_HZ])[0])[None, :]
    )
    np.testing.assert_allclose(np.abs(np.diag(L)), 1.0, rtol=1e-12)  # |G_ii M_i| = 1 at 110 Hz
    for i in range(3):
        assert np.count_nonzero(Kc.num[i][i]) == 3 and Kc.den[i][i].size == 3  # [2, 2] per axis (eq. 16)
        assert np.all(Kc.num[i][1 - i if i < 2 else 0] == 0)  # decentralised
    K = maglev.controller()
    assert K.dt == maglev.DT and K.n_states == 6


def test_reference_loop_is_stable_and_the_printed_pole_is_unreachable() -> None:
    K = maglev.controller()
    L = feedback(maglev.model().to_statespace(minimal=False).c2d(maglev.DT), K)
    assert L.is_stable()
    Lp = feedback(maglev.model(published=True).to_statespace(minimal=False).c2d(maglev.DT), K)
    s = np.log(Lp.poles().astype(complex)) / maglev.DT
    bad = s[s.real > 0]
    # the decentralised loops cannot move the +9.74 rad/s pole of eq. 22c: it stays put
    assert bad.size == 1 and bad[0].real == pytest.approx(9.74, rel=1e-2)


def test_chirp_experiment_columns_and_noise() -> None:
    t = maglev.EXPERIMENTS["chirp-y"](seed=1)
    assert t.names == ("r_x", "r_y", "r_phi", "Fx", "Fy", "Tphi", "x", "y", "phi")
    assert t.dt == maglev.DT and t.n_samples == 10000
    assert np.max(np.abs(t.column("r_y"))) == pytest.approx(1e-6, rel=1e-3) and np.all(t.column("r_x") == 0)
    clean = maglev.simulate_chirp("y", seed=1, snr_db=None)
    noise = t.column("y") - clean.column("y")
    snr = 20 * np.log10(np.std(clean.column("y")) / np.std(noise))
    assert snr == pytest.approx(80.0, abs=0.5)
