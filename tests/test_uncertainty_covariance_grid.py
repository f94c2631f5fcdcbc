"""Where the realised Hankel-MAP model's covariance is formed (stageid.subspace.uncertainty.grid_placement)."""

from __future__ import annotations

import numpy as np
import pytest

import stageid.subspace.uncertainty as unc
from _subspace_systems import band_limited, random_stage, record
from stageid._errors import DataError
from stageid.models import StateSpaceModel
from stageid.subspace import HankelMAP
from stageid.subspace.uncertainty.grid_placement import even_indices, placed_grid, quadrature_weights, resonances
from stageid.subspace.uncertainty.realisation_bias import local_misfit_bias


def modal_model(modes, dt=0.002):
    """Continuous modes ``(f_n, zeta)`` in a block-diagonal ``A``, discretised by ZOH."""
    n = 2 * len(modes)
    A, B, C = np.zeros((n, n)), np.ones((n, 1)), np.ones((1, n))
    for i, (f, z) in enumerate(modes):
        w = 2 * np.pi * f
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[0, 1], [-w * w, -2 * z * w]]
    return StateSpaceModel(A, B, C, np.zeros((1, 1)), None).c2d(dt)


def test_resonances_are_the_pole_pairs_damped_frequency_and_half_power_half_width():
    g = modal_model([(20.0, 0.01), (70.0, 0.02), (300.0, 0.01)])  # the third beyond the band
    got = resonances(g.A, g.dt, (1.0, 100.0))
    want = [[20.0 * np.sqrt(1 - 0.01**2), 0.2], [70.0 * np.sqrt(1 - 0.02**2), 1.4]]
    np.testing.assert_allclose(got, want, rtol=1e-9)
    # real poles are no resonance; an empty model has none
    assert resonances(np.diag([0.5, 0.9]), 0.002, (1.0, 100.0)).shape == (0, 2)
    assert resonances(np.zeros((0, 0)), 0.002, (1.0, 100.0)).shape == (0, 2)


def test_mode_placement_puts_points_in_every_narrow_half_power_band():
    # half-widths 1.2-1.3 Hz: narrower than the even grid's 4.5 Hz, wider than the fit's 0.5 Hz
    g = modal_model([(23.3, 0.05), (61.7, 0.02), (88.1, 0.015)])
    band, n_fit, budget = (1.0, 100.0), 200, 24
    even = np.linspace(*band, n_fit)[even_indices(n_fit, budget)]
    f, w = placed_grid(band, n_fit, budget, g.A, g.dt, "modes")
    assert f.size <= even.size  # no more points than the former grid
    assert np.all(np.diff(f) > 0) and f[0] >= band[0] and f[-1] <= band[1] < 0.5 / g.dt
    assert np.all(np.isin(f, np.linspace(*band, n_fit)))  # points of the fit's own grid
    assert w.sum() == pytest.approx(n_fit) and np.all(w > 0)
    for fd, h in resonances(g.A, g.dt, band):
        # 3 modes, 24 points: 1.9 quantile steps across each half-power band (module docstring)
        assert np.sum(np.abs(f - fd) <= h) >= 1, (fd, h, f)
    # a few points across each mode's circle (3 half-widths: 80 % of its arc); the even grid: <= 2
    for fd, h in resonances(g.A, g.dt, band):
        assert np.sum(np.abs(f - fd) <= 3 * h) >= 3
        assert np.sum(np.abs(even - fd) <= 3 * h) <= 2


def test_without_narrow_modes_the_former_even_grid():
    band, n_fit, budget = (1.0, 100.0), 200, 24
    even_f, even_w = placed_grid(band, n_fit, budget, np.zeros((0, 0)), 0.002, "even")
    for A in (np.diag([0.3, 0.8]), modal_model([(40.0, 0.4)]).A, np.zeros((0, 0))):  # real, well damped, none
        f, w = placed_grid(band, n_fit, budget, A, 0.002, "modes")
        np.testing.assert_array_equal(f, even_f)
        np.testing.assert_array_equal(w, even_w)
    # a narrow mode outside the band changes nothing either
    f, _ = placed_grid(band, n_fit, budget, modal_model([(150.0, 0.005)]).A, 0.002, "modes")
    np.testing.assert_array_equal(f, even_f)


def test_quadrature_weights_count_the_nearest_fit_frequencies():
    np.testing.assert_allclose(quadrature_weights(np.array([0, 3, 9]), 10), [2.0, 4.5, 3.5])
    np.testing.assert_allclose(quadrature_weights(np.arange(10), 10), np.ones(10))


@pytest.fixture(scope="module")
def siso_fit():
    g = random_stage(31, m=1, q=1, modes=3)  # resonances 13.6, 63, 82 Hz, half-widths 0.27-1.4 Hz
    exp = record(g, band_limited(6000, 1, g.dt, 0), 0.01, 0, names=False)
    return HankelMAP(order=g.n_states, horizon=30).fit(exp)


def test_std_on_mode_grid_matches_the_fits_full_grid(siso_fit, monkeypatch):
    # the reference: the covariance on every frequency of the realisation's fit (200), i.e. its
    # own sum; 24 frequencies placed at the modes reproduce its std within 10 % everywhere and 3 %
    # in the median (the quadrature error of a resolved response; measured 4.1 and 1.9 %; without
    # the quadrature weights 8.7 and 4.8 %), the former even 24 do not (2.9x at one point)
    f = np.geomspace(1.5, 98.0, 200)
    monkeypatch.setattr(unc, "MAX_OVERLAP_COLUMNS", 10**6)
    ref = unc.realised_response_uncertainty(siso_fit, f, bias="none").std
    monkeypatch.setattr(unc, "MAX_OVERLAP_COLUMNS", 24)
    modes = unc.realised_response_uncertainty(siso_fit, f, bias="none", grid="modes").std
    even = unc.realised_response_uncertainty(siso_fit, f, bias="none", grid="even").std
    assert np.max(np.abs(modes / ref - 1)) < 0.1
    assert np.median(np.abs(modes / ref - 1)) < 0.03
    assert np.max(np.abs(even / ref - 1)) > 0.1  # the case needs the placement


def test_unknown_grid_is_a_data_error(siso_fit):
    with pytest.raises(DataError, match="grid"):
        unc.realised_response_uncertainty(siso_fit, [10.0], grid="log")


def test_misfit_test_on_an_uneven_grid_holds_its_level():
    # pure noise, the noise of three points (the resonance's) 50x the rest: the weighted test
    # with Satterthwaite's degrees of freedom rejects ~1 % of the 4000 draws; two degrees of
    # freedom per point would reject far more (the sum is dominated by three points)
    rng = np.random.default_rng(5)
    grid = np.linspace(1.0, 100.0, 23)
    weights = rng.uniform(2.0, 15.0, grid.size)
    noise = np.ones((grid.size, 1, 4000))
    noise[[8, 9, 10]] *= 50.0
    misfit = noise * rng.exponential(size=noise.shape)  # |r|^2 of a circular Gaussian of variance noise
    G = np.ones_like(noise)
    b2 = local_misfit_bias(grid, misfit, noise, G, np.array([50.0]), weights)
    rejected = np.mean(b2[0, 0] > 0)
    assert rejected < 0.025
