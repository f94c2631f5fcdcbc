"""Starts that add a lightly damped mode where an output-error fit's residual still follows the input."""

from __future__ import annotations

import numpy as np
import scipy.signal as ss

from stageid.closedloop import pem
from stageid.closedloop.mode_injection import explained_residual_peaks, with_modes


def _mode(w: float, zeta: float) -> np.ndarray:
    rho = np.exp(-zeta * w)
    return np.array([1.0, -2 * rho * np.cos(w), rho**2])


def _records():
    """A well damped pair plus a lightly damped mode at 0.4 rad/sample, white input, two records."""
    F = np.convolve(_mode(0.05, 0.5), _mode(0.4, 0.01))
    B = np.array([0.02, 0.01, -0.005, 0.002])
    rng = np.random.default_rng(7)
    us = [rng.standard_normal(6000) for _ in range(2)]
    return [(u, ss.lfilter(np.concatenate([[0.0], B]), F, u) + 1e-4 * rng.standard_normal(u.size)) for u in us]


def test_the_peak_is_the_mode_the_model_leaves_out():
    segs = _records()
    # a second-order fit holds the slow pair and leaves the mode at 0.4 rad/sample in the residual
    m = pem([u for u, _ in segs], [y for _, y in segs], "oe", {"nb": 2, "nf": 2})
    (w,) = explained_residual_peaks(m, segs, 1)
    assert abs(w - 0.4) < 3 * 2 * np.pi / 2048  # within the Welch segment's line spacing, three lines


def test_added_modes_leave_the_response_and_raise_the_order_by_two_each():
    segs = _records()
    m = pem([u for u, _ in segs], [y for _, y in segs], "oe", {"nb": 2, "nf": 2})
    m2 = with_modes(m, [0.4, 1.1])
    assert m2.F.size == m.F.size + 4 and m2.B.size == m.B.size + 4
    f = np.linspace(1e-3, 0.49, 200)  # dt = 1: Hz is cycles per sample
    np.testing.assert_allclose(m2.frequency_response(f), m.frequency_response(f), rtol=1e-9)  # cancelling pairs


def test_the_fit_restarted_with_the_mode_reaches_the_noise_floor():
    segs = _records()
    u, y = [s[0] for s in segs], [s[1] for s in segs]
    m = pem(u, y, "oe", {"nb": 2, "nf": 2})
    m4 = pem(u, y, "oe", {"nb": 4, "nf": 4}, initial=with_modes(m, explained_residual_peaks(m, segs, 1)))
    assert m4.loss < 2.0 * 1e-8  # the noise's variance (1e-4)^2; the order-2 fit is far above it
    assert m.loss > 100 * 1e-8
