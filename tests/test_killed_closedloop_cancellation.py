"""Tests that kill surviving mutants of ``closedloop/cancellation.py`` and ``closedloop/deduction.py``
(tests/MUTATION.md): small hand-built systems whose answer is known without the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from stageid._errors import IdentificationError
from stageid.closedloop.cancellation import cancel_entries, cancel_pairs, pole_contributions
from stageid.closedloop.deduction import check_controller, check_grid, deduce_response, unstable_plant_poles
from stageid.models import StateSpaceModel, TransferMatrix, feedback

DT = 1e-3


def _siso(num, den) -> StateSpaceModel:
    return TransferMatrix([[num]], [[den]], DT).to_statespace(minimal=False)


def test_pole_contributions_are_the_modal_residues_over_the_entrys_peak() -> None:
    # G(z) = 1 / (z - 0.9) + 0.01 / (z - 0.5): residues 1 and 0.01, read off the diagonal form
    g = StateSpaceModel(np.diag([0.9, 0.5]), [[1.0], [1.0]], [[1.0, 0.01]], [[0.0]], DT)
    f = np.array([0.1, 10.0, 100.0, 400.0])
    z = np.exp(2j * np.pi * f * DT)
    peak = np.max(np.abs(1 / (z - 0.9) + 0.01 / (z - 0.5)))
    out = pole_contributions(g, np.array([0.9, 0.5]), f)
    assert out.shape == (2, 1, 1)
    np.testing.assert_allclose(
        out[:, 0, 0], [np.max(np.abs(1 / (z - 0.9))) / peak, np.max(np.abs(0.01 / (z - 0.5))) / peak]
    )


def test_entry_with_a_large_gain_cancels_its_near_pair() -> None:
    # G = 100 (z - 0.8) / ((z - 0.8001)(z - 0.5)): one pole-zero pair 5.6e-4 apart (relative,
    # s-plane) -- cancelled, leaving 100 / (z - 0.5); the entry is normalised to unit B and C
    # before its zeros are computed, so the gain must not leak into them
    g = _siso(100.0 * np.poly([0.8]), np.poly([0.8001, 0.5]))
    _, (rep,) = cancel_entries(g)
    assert len(rep.pairs) == 1
    assert rep.pairs[0].pole == pytest.approx(np.log(0.8001) / DT)
    assert rep.pairs[0].zero == pytest.approx(np.log(0.8) / DT)
    np.testing.assert_allclose(rep.kept_poles, [0.5], rtol=1e-9)
    assert rep.kept_zeros.size == 0 and rep.gain == pytest.approx(100.0, rel=1e-3)  # fitted with the pair gone


def test_loose_tolerance_only_for_an_unstable_pole_facing_an_unstable_zero() -> None:
    # s-plane distance 2.5 / 100 = 0.025: above tol (0.01), below unstable_tol (0.25)
    z = lambda s: np.exp(np.array([s]) * DT)  # noqa: E731
    kp, kz, pairs = cancel_pairs(z(-0.5 + 100j), z(2.0 + 100j), DT)  # stable pole: strict tolerance
    assert len(pairs) == 0 and kp.size == 1 and kz.size == 1
    kp, kz, pairs = cancel_pairs(z(0.5 + 100j), z(3.0 + 100j), DT)  # both unstable: loose
    assert len(pairs) == 1 and kp.size == 0 and kz.size == 0
    kp, kz, pairs = cancel_pairs(z(0.5 + 100j), z(-2.0 + 100j), DT)  # stable zero: strict
    assert len(pairs) == 0


def test_controller_zero_outside_the_unit_circle_is_no_plant_pole() -> None:
    G = _siso([1.0], [1.0, -1.1])  # unstable plant pole z = 1.1
    M = _siso(0.3 * np.array([1.0, -1.5]), [1.0, -0.2])  # non-minimum-phase controller zero z = 1.5
    L = feedback(G, M)
    T = StateSpaceModel(L.A, L.B, L.C[:1], L.D[:1], DT)
    np.testing.assert_allclose(unstable_plant_poles(T, M), [1.1], rtol=1e-8)


def test_singular_controller_names_the_first_frequency_and_the_relative_size() -> None:
    # M = (z - 1 + 1e-9)(z + 1 - 1e-9) / z^2: almost zero at 0 Hz and at Nyquist, peak 2 near fs / 4
    M = _siso(np.poly([1 - 1e-9, -1 + 1e-9]), [1.0, 0.0, 0.0])
    f = np.array([0.0, 125.0, 250.0, 375.0, 500.0])
    K = np.abs(np.polyval(np.poly([1 - 1e-9, -1 + 1e-9]), np.exp(2j * np.pi * f * DT)))
    ratio = K[0] / K.max()
    with pytest.raises(IdentificationError, match=rf"singular at 0 Hz: .* {ratio:.2g} of its peak gain"):
        check_controller(M, f)


def test_check_grid_starts_a_decade_below_the_band_and_at_most_at_1_hz() -> None:
    for f_low, first in ((5.0, 0.5), (50.0, 1.0)):
        grid = check_grid(f_low, DT)
        assert grid.size == 401 and grid[0] == 0.0
        assert grid[1] == pytest.approx(first, rel=1e-12) and grid[-1] == pytest.approx(0.95 * 0.5 / DT, rel=1e-12)


def test_deduce_response_refuses_arrays_that_are_not_frequency_stacks_of_square_matrices() -> None:
    T = np.full((2, 2, 2, 2), 0.5 + 0j)  # 4-d: not (n_freqs, p, p)
    with pytest.raises(IdentificationError, match=r"must all have shape \(n_freqs, p, p\)"):
        deduce_response(T, np.ones_like(T))
