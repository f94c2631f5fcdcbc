"""Tests written to kill survivors of the ``disturbance-modes`` mutation group (tests/MUTATION.md).

The residuals are white noise rung through resonances away from the drives' harmonics (the
100 Hz drive's record leaves out the bins beside multiples of 100 Hz, rule 3).
"""

import numpy as np
import pytest
from scipy.signal import lfilter

from stageid.hysteresis.stage.disturbance_modes import disturbance_modes
from test_stage_disturbance_modes import DT, _drive, _resonance

DRIVES = [_drive(20.0, 1.5), _drive(100.0, 0.6)]


def _rung(modes, seed):
    """Per drive: ``sum(gain * R(f_n, zeta)[white])`` plus a little white sensor noise."""
    rng = np.random.default_rng(seed)
    out = []
    for u in DRIVES:
        e = 0.05 * rng.standard_normal(u.size)
        for f_n, zeta, gain in modes:
            b, a = _resonance(f_n, zeta)
            e += gain * lfilter(b, a, rng.standard_normal(u.size))
        out.append(e)
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_separated_modes_are_both_found_when_the_stronger_is_higher(seed):
    # the band a taken mode excludes is fn (1 +- SEPARATION zeta): it must not reach down to 650 Hz
    found = disturbance_modes(_rung([(650.0, 0.01, 1.0), (1750.0, 0.01, 3.0)], seed), DRIVES, DT)
    assert len(found) == 2, found
    for mode, (f_n, zeta) in zip(found, [(650.0, 0.01), (1750.0, 0.01)], strict=True):
        assert abs(mode.frequency_hz - f_n) < 0.02 * f_n
        assert zeta / 1.6 < mode.damping < zeta * 1.6


@pytest.mark.parametrize("zeta", [0.0005, 0.003])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_resonance_narrower_than_one_bin_gives_no_mode(zeta, seed):
    # half-power width 2 zeta fn below the ~9.8 Hz bin: a line, not a mode the spectrum can
    # resolve; without the rule the fit returns dampings at its bound and invents a second mode
    assert 2 * zeta * 1250.0 < 1 / (1024 * DT)
    assert disturbance_modes(_rung([(1250.0, zeta, 1.0)], seed), DRIVES, DT) == ()
