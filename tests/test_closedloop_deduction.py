"""Plant deduction G = T (M - M T)^-1 (eq. 18): algebra, state space, unstable poles, cancellation."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from stageid._errors import IdentificationError
from stageid.closedloop import (
    cancel_entries,
    cancel_pairs,
    deduce_plant,
    deduce_response,
    deduce_siso,
    unstable_plant_poles,
)
from stageid.models import StateSpaceModel, feedback

sys.path.insert(0, str(Path(__file__).parent))
from _closedloop_plant2x2 import DT, UNSTABLE, controller, plant  # noqa: E402


def _true_closed_loop() -> tuple[StateSpaceModel, StateSpaceModel, StateSpaceModel]:
    G = plant().to_statespace(minimal=False).c2d(DT)
    K = controller()
    L = feedback(G, K)
    T = StateSpaceModel(L.A, L.B, L.C[:2], L.D[:2], DT)  # r -> y
    return G, K, T


def test_eq18_inverts_eq15_for_random_complex_matrices() -> None:
    rng = np.random.default_rng(0)
    G = rng.standard_normal((5, 3, 3)) + 1j * rng.standard_normal((5, 3, 3))
    M = rng.standard_normal((5, 3, 3)) + 1j * rng.standard_normal((5, 3, 3))
    I = np.eye(3)
    T = np.linalg.solve(I + G @ M, G @ M)  # eq. 15, MIMO: (I + G M)^-1 G M
    np.testing.assert_allclose(deduce_response(T, M), G, rtol=1e-9, atol=1e-12)


def test_two_degree_of_freedom_law() -> None:
    rng = np.random.default_rng(1)
    G = rng.standard_normal((4, 2, 2)) + 1j * rng.standard_normal((4, 2, 2))
    M = rng.standard_normal((4, 2, 2)) + 1j * rng.standard_normal((4, 2, 2))
    Mr = rng.standard_normal((4, 2, 2)) + 1j * rng.standard_normal((4, 2, 2))
    T = np.linalg.solve(np.eye(2) + G @ M, G @ Mr)  # u = M_r r - M y
    np.testing.assert_allclose(deduce_response(T, M, Mr), G, rtol=1e-9, atol=1e-12)


def test_state_space_deduction_recovers_unstable_mimo_plant() -> None:
    G, K, T = _true_closed_loop()
    Gh = deduce_plant(T, K)
    f = np.geomspace(1.0, 2000.0, 40)
    # exact T: only rounding separates the deduction from the plant (non-minimal, ill-conditioned realisation)
    np.testing.assert_allclose(Gh.frequency_response(f), G.frequency_response(f), rtol=1e-5, atol=1e-14)


def test_unstable_poles_come_from_the_zeros_of_the_sensitivity() -> None:
    _, K, T = _true_closed_loop()
    z = unstable_plant_poles(T, K)
    s = np.sort(np.log(z).real / DT)
    np.testing.assert_allclose(s, UNSTABLE, rtol=1e-6)


def test_siso_polynomials_carry_the_spurious_pairs() -> None:
    # G = 1/(z - 1.1) (unstable), M = 0.5: T = 0.5 / (z - 0.6)
    num, den = deduce_siso([0.0, 0.5], [1.0, -0.6], [0.5], [1.0])
    poles = np.sort(np.roots(den).real)
    zeros = np.sort(np.roots(num).real) if np.count_nonzero(num) > 1 else np.zeros(0)
    np.testing.assert_allclose(poles, [0.6, 1.1])  # A = z - 0.6 and A - B = z - 1.1
    np.testing.assert_allclose(zeros, [0.6])  # A again: a spurious pair
    kp, kz, pairs = cancel_pairs(np.roots(den), np.roots(num), dt=1e-3)
    np.testing.assert_allclose(kp.real, [1.1])
    assert len(pairs) == 1 and pairs[0].distance < 1e-12


def test_cancellation_leaves_the_true_plant_order_on_the_diagonal() -> None:
    G, K, T = _true_closed_loop()
    Gc, entries = cancel_entries(deduce_plant(T, K))
    by_entry = {(e.output, e.input): e for e in entries}
    for i in range(2):
        e = by_entry[(i, i)]
        assert e.kept_poles.size == 2  # [0, 2]: the plant's own two poles ...
        s = np.sort(np.log(e.kept_poles).real / DT)
        assert np.min(np.abs(s - UNSTABLE[i])) < 1e-3 * UNSTABLE[i]  # ... one of them the unstable one
        assert max(p.distance for p in e.pairs) < 1e-3  # exact T: spurious pairs cancel tightly
    f = np.geomspace(20, 300, 30)
    for i in range(2):
        np.testing.assert_allclose(Gc.frequency_response(f)[:, i, i], G.frequency_response(f)[:, i, i], rtol=1e-4)
    # the couplings keep at least their three plant poles (the controller's slow lag pair may
    # survive when the pencil zeros of the 36-state entry are inaccurate; the reduction removes it)
    assert by_entry[(0, 1)].kept_poles.size >= 3 and by_entry[(1, 0)].kept_poles.size >= 3


def test_dimension_and_properness_errors() -> None:
    _, K, T = _true_closed_loop()
    K1 = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.0]], DT)
    with pytest.raises(IdentificationError, match="controller must map"):
        deduce_plant(T, K1)
    Kstrict = StateSpaceModel(K.A, K.B, K.C, np.zeros((2, 2)), DT)
    with pytest.raises(IdentificationError, match="biproper"):
        deduce_plant(T, Kstrict)
    with pytest.raises(IdentificationError, match="singular"):
        deduce_response(np.zeros((2, 1, 1)), np.array([[[1.0]], [[0.0]]]))
