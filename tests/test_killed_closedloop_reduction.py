"""Tests that kill surviving mutants of ``closedloop/reduction.py`` and ``plant_reduction.py`` (tests/MUTATION.md).

Each pins one documented rule of the reduction that the end-to-end closed-loop tests reach
only through a whole identification, where a wrong rule is hidden by another route (for
example the all-poles-free fit stands in when no unstable pole is kept).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from stageid._errors import IdentificationError
from stageid.closedloop.cancellation import EntryPoleZero
from stageid.closedloop.plant_reduction import entry_unstable_poles, keep_full_order
from stageid.closedloop.reduction import paper_orders, reduce_entry
from stageid.closedloop.zoh import zoh_response
from stageid.models import TransferMatrix

DT = 2e-4


def _entry(kept_poles_s: list[complex], extra_z: list[complex] = ()) -> EntryPoleZero:
    z = np.concatenate([np.exp(np.asarray(kept_poles_s, dtype=complex) * DT), np.asarray(extra_z, dtype=complex)])
    return EntryPoleZero(0, 0, z, np.zeros(0), z, np.zeros(0), 1.0, ())


def test_entry_unstable_poles_keeps_only_the_outside_poles_snapped_to_the_plants() -> None:
    # 50.4 rad/s is within 5 % of the plant's 50 -> snapped; 200 is no plant pole -> kept as is;
    # the stable pole (-80), the integrator on the unit circle (z = 1) and z = 0 are not unstable
    ent = _entry([50.4, -80.0, 200.0], extra_z=[1.0, 0.0])
    out = entry_unstable_poles(ent, np.array([50.0, 500.0]), DT)
    assert np.all(out.imag == 0)  # real poles come back real
    assert out.real.tolist() == pytest.approx([50.0, 200.0], rel=1e-9)
    assert out[0] == 50.0  # the plant's value itself, not the entry's


def test_entry_unstable_poles_uses_each_plant_pole_once_and_keeps_complex_pairs() -> None:
    # two entry poles near the same plant pole: the nearer first in the entry's order takes it
    ent = _entry([50.5, 51.0, 30 + 40j, 30 - 40j])
    out = entry_unstable_poles(ent, np.array([50.0, 30 + 40.5j, 30 - 40.5j]), DT)
    assert out[0] == 50.0 and out[1] == pytest.approx(51.0, rel=1e-9)
    assert out[2] == 30 + 40.5j and out[3] == 30 - 40.5j
    # outside the 5 % snapping distance the entry's own value is kept
    far = entry_unstable_poles(_entry([54.0]), np.array([50.0]), DT)
    assert far.real.tolist() == pytest.approx([54.0], rel=1e-9)
    # a real pole that picked up a rounding-size imaginary part (< 1e-9 relative) comes back real
    almost = entry_unstable_poles(_entry([200.0 + 1e-8j]), np.zeros(0), DT)
    assert almost.imag.tolist() == [0.0] and almost.real == pytest.approx(200.0, rel=1e-9)
    assert entry_unstable_poles(_entry([200.0 + 1e-5j]), np.zeros(0), DT).imag == pytest.approx(1e-5, rel=1e-3)
    assert entry_unstable_poles(_entry([54.0]), np.array([50.0]), DT, rel=0.1).tolist() == [50.0]


def test_reduce_entry_needs_n_zeros_plus_free_poles_plus_two_frequencies() -> None:
    f = np.geomspace(20, 300, 4)  # [1, 3] with one pole kept: 1 + 2 free + 2 = 5 needed
    P = zoh_response([1.0, 3.0], np.poly([50.0, -80.0, -120.0]), DT, np.geomspace(20, 300, 5))
    with pytest.raises(IdentificationError, match="at least 5 frequencies"):
        reduce_entry(P[:4], f, DT, 1, 3, np.array([50.0]))
    red = reduce_entry(P, np.geomspace(20, 300, 5), DT, 1, 3, np.array([50.0]))  # exactly 5: accepted
    assert red.eps_complex < 1e-6


def test_reduce_entry_rejects_a_band_that_does_not_match_the_response() -> None:
    f = np.geomspace(20, 300, 8)
    P = zoh_response([3.0], np.poly([50.0, -80.0]), DT, f)
    with pytest.raises(IdentificationError, match="got 8 and 7"):
        reduce_entry(P[:7], f, DT, 0, 2)  # enough points for [0, 2], but one short of the band


def _plant2x2_discrete():
    sys.path.insert(0, str(Path(__file__).parent))
    from _closedloop_plant2x2 import plant

    return plant().c2d(DT, "zoh")


def test_keep_full_order_reports_each_entrys_band_error() -> None:
    G = _plant2x2_discrete()
    f = np.geomspace(20, 300, 30)
    scale = np.array([[0.01, 0.02], [0.03, 0.04]])  # a different constant error per entry
    response = G.frequency_response(f) * (1 + scale)
    plant, reduced, eps, eps_c = keep_full_order(G, response, f, continuous=False)
    assert plant is G and reduced == {}
    assert eps.shape == eps_c.shape == (2, 2)
    np.testing.assert_allclose(eps_c, scale / (1 + scale), rtol=1e-9)  # |P - P r| / |P| per entry
    np.testing.assert_allclose(eps, scale / (1 + scale), rtol=1e-9)
    worse = scale.copy()
    worse[1, 0] = 0.06  # one entry beyond the 5 % limit: named in the error
    with pytest.raises(IdentificationError, match=r"entry \(1, 0\) misses the deduced response by 5\.7 %"):
        keep_full_order(G, G.frequency_response(f) * (1 + worse), f, continuous=False)


def test_full_order_continuous_plant_with_small_discrete_gains() -> None:
    G = TransferMatrix([[[3.0]]], [[np.poly([50.0, -80.0])]], None, ("F",), ("x",)).c2d(DT, "zoh")
    f = np.geomspace(20, 300, 30)
    plant, _, _, eps_c = keep_full_order(G, G.frequency_response(f), f, continuous=True)
    assert plant.dt is None and eps_c.max() < 1e-6


def test_stable_free_keeps_the_free_poles_in_the_left_half_plane() -> None:
    f = np.geomspace(20, 300, 40)
    P = zoh_response([3.0], np.poly([50.0, -80.0]), DT, f)  # an unstable entry, no pole kept
    free = reduce_entry(P, f, DT, 0, 2, stable_free=False)
    assert np.max(free.poles.real) == pytest.approx(50.0, rel=1e-6)  # fitted, not kept
    stable = reduce_entry(P, f, DT, 0, 2, stable_free=True)
    assert np.all(stable.poles.real < 0)


def test_paper_orders_diagonal_0_2_couplings_1_3() -> None:
    # eq. 22a/23a/24a: [0, 2] on the diagonal; eq. 22b-24c: third-order couplings, up to one zero
    assert paper_orders(2) == {(0, 0): (0, 2), (0, 1): (1, 3), (1, 0): (1, 3), (1, 1): (0, 2)}
    assert paper_orders(1) == {(0, 0): (0, 2)}


def test_zoh_response_of_a_static_gain() -> None:
    f = np.array([0.0, 10.0, 2000.0])
    np.testing.assert_array_equal(zoh_response([2.5], [1.0], DT, f), np.full(3, 2.5 + 0j))


def test_reduce_entry_structure_bounds() -> None:
    f = np.geomspace(20, 300, 30)
    # biproper [1, 1] is allowed (n_zeros == n_poles) ...
    P = zoh_response([1.0, 10.0], [1.0, 80.0], DT, f)
    assert reduce_entry(P, f, DT, 1, 1).eps_complex < 1e-6
    # ... an improper [3, 2] is not
    with pytest.raises(IdentificationError, match=r"0 <= n_zeros <= n_poles .* got \[3, 2\]"):
        reduce_entry(P, f, DT, 3, 2)
