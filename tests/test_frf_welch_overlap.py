"""Welch's overlap correction (Welch 1967, eq. 14) against its closed form for the Hann window,
and the standard deviation it sets calibrated at 50 % and 75 % overlap."""

import numpy as np
import pytest
import scipy.signal as ss

from stageid.data import Experiment
from stageid.frf import cross_spectra, welch_frf

DT = 1e-3

# Overlap correlations rho(k) of the periodic Hann window at shifts of k quarters of a segment,
# integrals of sin^2(pi t) sin^2(pi (t + s)) over the overlap divided by 3/8 (Harris 1978, table 1:
# 16.7 % at 50 %, 65.9 % at 75 % overlap).
RHO_HALF = 1.0 / 6.0
RHO_QUARTER = (np.pi + 1.0) / (2.0 * np.pi)
RHO_THREE_QUARTERS = (np.pi - 3.0) / (6.0 * np.pi)


def _welch_l_eff(n_segments: int, rhos: list[float]) -> float:
    """``L / (1 + 2 sum_k (1 - k/L) rho(k)^2)`` (Welch 1967, eq. 14)."""
    L = n_segments
    return L / (1.0 + 2.0 * sum((1.0 - k / L) * r * r for k, r in enumerate(rhos, start=1)))


@pytest.mark.parametrize(
    "overlap, rhos",
    [(0.0, []), (0.5, [RHO_HALF]), (0.75, [RHO_QUARTER, RHO_HALF, RHO_THREE_QUARTERS])],
)
def test_effective_segments_equal_welchs_formula_for_hann(overlap, rhos):
    segment = 4096  # the discrete sums approach the integrals to O(1 / segment)
    n = segment * 6
    u = np.random.default_rng(0).standard_normal(n)
    cs = cross_spectra(Experiment(u, u, DT), segment, overlap=overlap)
    step = segment - int(overlap * segment)
    assert cs.n_segments == (n - segment) // step + 1
    np.testing.assert_allclose(cs.effective_segments, _welch_l_eff(cs.n_segments, rhos), rtol=2e-3)


def test_effective_segments_add_over_records_each_with_its_own_count():
    # two records of 9 and 3 segments at 75 % overlap: L_eff(9) + L_eff(3), not L_eff(12)
    segment = 4096
    rng = np.random.default_rng(1)
    rhos = [RHO_QUARTER, RHO_HALF, RHO_THREE_QUARTERS]
    recs = [Experiment(x, x, DT) for x in (rng.standard_normal(segment * 3), rng.standard_normal(segment * 3 // 2))]
    cs = cross_spectra(recs, segment, overlap=0.75)
    assert cs.n_segments == 12
    expected = _welch_l_eff(9, rhos) + _welch_l_eff(3, rhos)
    np.testing.assert_allclose(cs.effective_segments, expected, rtol=2e-3)


@pytest.mark.parametrize("overlap", [0.5, 0.75])
def test_welch_std_is_calibrated_at_half_and_three_quarter_overlap(overlap):
    # An FIR system much shorter than a segment: no leakage bias, so the error is the noise the
    # std describes.  The RMS of |H - H_true| / std pooled over 24 records has a sampling spread
    # of about 3 %; without the overlap correction it is 1.39 at 75 % overlap.
    b = [1.0, 0.5, -0.3]
    ratios = []
    for seed in range(24):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(2**14)
        y = ss.lfilter(b, [1.0], u) + 0.3 * rng.standard_normal(u.size)
        frd = welch_frf(Experiment(u, y, DT), 256, overlap=overlap)
        H = np.polyval(b[::-1], np.exp(-2j * np.pi * frd.freqs * DT))
        ratios.append(np.mean(np.abs(frd.response[:, 0, 0] - H) ** 2 / frd.std[:, 0, 0] ** 2))
    ratio = float(np.sqrt(np.mean(ratios)))
    assert 0.9 <= ratio <= 1.1, ratio
