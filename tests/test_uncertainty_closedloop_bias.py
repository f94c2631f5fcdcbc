"""The closed-loop reduction's bias rule that follows the misfit along the band."""

from __future__ import annotations

import numpy as np

from stageid.closedloop.uncertainty import LOCAL_WINDOW, local_bias

FB = np.geomspace(20.0, 300.0, 120)  # the estimator's reduction grid


def test_a_flat_excess_gives_the_flat_rule():
    misfit = np.full((FB.size, 2, 2), 3e-6)
    noise = np.full((FB.size, 2, 2), 1e-6)
    f = np.geomspace(5.0, 1000.0, 50)  # inside and outside the band
    np.testing.assert_allclose(local_bias(FB, misfit, noise, f), 2e-6, rtol=1e-12)


def test_the_excess_is_followed_along_the_band_and_held_outside():
    # a misfit 100x larger in the lowest quarter (as the deduced response's error on the maglev)
    misfit = np.where(FB < 39.0, 1e-4, 1e-6)[:, None, None] * np.ones((1, 1, 1))
    noise = np.zeros_like(misfit)
    flat = misfit.mean()  # what bias="flat" would add at every frequency
    got = local_bias(FB, misfit, noise, np.array([10.0, 20.0, 25.0, 150.0, 300.0, 600.0]))[:, 0, 0]
    assert got[1] > 1.8 * flat and got[2] > 3 * flat  # the low end gets its own, larger, misfit
    np.testing.assert_allclose(got[3:5], 1e-6, rtol=1e-9)  # far from the step: its own level
    # outside the band: the larger of the edge's value and the band's mean (the flat rule's)
    assert got[0] == got[1]
    np.testing.assert_allclose(got[5], flat, rtol=1e-9)
    # the step is smeared over at most the window on either side
    h = int(round(LOCAL_WINDOW * FB.size))
    inside = local_bias(FB, misfit, noise, FB)[:, 0, 0]
    k = int(np.searchsorted(FB, 39.0))
    np.testing.assert_allclose(inside[: max(k - h, 0)], 1e-4, rtol=1e-9)
    np.testing.assert_allclose(inside[k + h :], 1e-6, rtol=1e-9)


def test_an_excess_below_the_noise_adds_nothing():
    misfit = np.full((FB.size, 1, 1), 1e-6)
    noise = np.full((FB.size, 1, 1), 2e-6)
    assert np.all(local_bias(FB, misfit, noise, FB) == 0.0)
