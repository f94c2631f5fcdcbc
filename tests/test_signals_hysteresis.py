"""Decaying sine/triangle and FORC staircase: envelopes, reversal steps, real records."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from stageid import SignalError
from stageid.signals import (
    decay_envelope,
    decaying_sine,
    decaying_triangle,
    forc_staircase,
    time_vector,
)

DSPACE = Path(__file__).resolve().parents[2] / "shared" / "data" / "piezo_dspace_preisach"


def _cycle_extrema(x: np.ndarray, samples_per_cycle: int, offset: float) -> tuple[np.ndarray, np.ndarray]:
    cycles = (x - offset).reshape(-1, samples_per_cycle)
    return cycles.max(axis=1), cycles.min(axis=1)


@pytest.mark.parametrize("func", [decaying_sine, decaying_triangle])
@pytest.mark.parametrize("decay", ["linear", "exponential"])
def test_decaying_envelope_monotone_and_full_range_first(func, decay):
    # Fig. 4 of the modified-PI letter: -500..500 V, amplitude shrinking cycle by cycle
    f, dt, n_c = 2.0, 1e-3, 12  # 500 samples per cycle, a multiple of 4: peaks sampled
    x = func(f, n_c, dt, amplitude=500.0, decay=decay, limits=(-500.0, 500.0))
    assert x.shape == (n_c * 500,)
    hi, lo = _cycle_extrema(x, 500, 0.0)
    env = decay_envelope(n_c, 500.0, decay)
    np.testing.assert_allclose(hi, env, rtol=1e-12)
    np.testing.assert_allclose(-lo, env, rtol=1e-12)
    assert hi[0] == pytest.approx(500.0) and lo[0] == pytest.approx(-500.0)  # whole range
    assert np.all(np.diff(hi) < 0) and np.all(np.diff(lo) > 0)  # strictly shrinking
    assert hi[-1] < 0.1 * 500.0  # decays towards zero
    assert x[0] == 0.0


@pytest.mark.parametrize("func, slope", [(decaying_sine, 2 * np.pi), (decaying_triangle, 4.0)])
def test_decaying_signal_is_continuous(func, slope):
    f, dt = 1.0, 1e-3
    x = func(f, 6, dt, amplitude=2.0, offset=1.0)
    # no jump anywhere: steps bounded by the steepest slope (slope * A * f) of cycle 0
    assert np.max(np.abs(np.diff(x))) <= slope * 2.0 * f * dt * (1 + 1e-9)
    assert abs(x[-1] - 1.0) < slope * 2.0 * f * dt  # ends back near the offset


def test_decay_envelope_laws():
    np.testing.assert_allclose(decay_envelope(5, 10.0), [10.0, 8.0, 6.0, 4.0, 2.0])
    np.testing.assert_allclose(decay_envelope(5, 10.0, final_fraction=0.6), [10.0, 9.0, 8.0, 7.0, 6.0])
    e = decay_envelope(6, 3.0, "exponential", final_fraction=0.1)
    np.testing.assert_allclose(e[1:] / e[:-1], 0.1 ** (1 / 5), rtol=1e-12)  # constant ratio
    assert e[0] == 3.0 and e[-1] == pytest.approx(0.3)


def test_decaying_triangle_values_at_known_times():
    x = decaying_triangle(1.0, 2, 0.125, amplitude=4.0, offset=10.0)
    assert x.tolist() == [10.0, 12.0, 14.0, 12.0, 10.0, 8.0, 6.0, 8.0, 10.0, 11.0, 12.0, 11.0, 10.0, 9.0, 8.0, 9.0]


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(freq=1.0, n_cycles=1, dt=1e-3), "`n_cycles` of decaying signal must be an integer >= 2; got 1"),
        (dict(freq=1.0, n_cycles=5, dt=1e-3, final_fraction=1.0), "must be in (0, 1) so the amplitude decays; got 1"),
        (dict(freq=1.0, n_cycles=5, dt=1e-3, decay="cosine"), "'linear', 'exponential'; got 'cosine'"),
        (dict(freq=600.0, n_cycles=5, dt=1e-3), "Nyquist frequency 1/(2 dt) = 500 Hz; got 600 Hz"),
        (dict(freq=1.0, n_cycles=5, dt=0.0), "`dt` of decaying sine must be a number > 0; got 0"),
        (
            dict(freq=1.0, n_cycles=5, dt=1e-3, amplitude=-3.0),
            "`amplitude` of decaying signal must be a number > 0; got -3",
        ),
    ],
)
def test_decaying_parameter_errors(kwargs, fragment):
    with pytest.raises(SignalError, match=re.escape(fragment)):
        decaying_sine(**kwargs)


def test_decaying_limits_error():
    with pytest.raises(SignalError, match=re.escape("decaying triangle spans [-500, 500] but limits are [-400, 500].")):
        decaying_triangle(1.0, 4, 1e-3, amplitude=500.0, limits=(-400.0, 500.0))


# ------------------------------------------------------------------------------- FORC


@pytest.mark.parametrize("shape", ["triangle", "cosine"])
def test_forc_reversal_maxima_rise_in_equal_steps(shape):
    lo, hi, n_r, f, dt = -90.0, 90.0, 50, 20.0, 1e-4
    x = forc_staircase(lo, hi, n_r, f, dt, shape=shape, idle=0.2)
    n_idle, per = 2000, 500
    assert x.shape == (n_idle + n_r * per,)
    assert np.all(x[:n_idle] == lo)
    # reversal points: where the slope changes sign
    idx = np.nonzero(np.diff(np.sign(np.diff(x))) < 0)[0] + 1
    maxima = x[idx]
    assert maxima.size == n_r
    np.testing.assert_allclose(np.diff(maxima), (hi - lo) / n_r, rtol=1e-9)  # 3.6 V steps
    assert maxima[0] == pytest.approx(lo + 3.6) and maxima[-1] == pytest.approx(hi)
    # each cycle lasts 1/f: maxima half a cycle after each cycle start
    np.testing.assert_array_equal(idx, n_idle + per // 2 + per * np.arange(n_r))
    # and every cycle returns to the minimum
    np.testing.assert_allclose(x[n_idle::per], lo, atol=1e-12)
    assert x.min() == lo and x.max() == hi


def test_forc_triangle_has_straight_ramps():
    x = forc_staircase(0.0, 4.0, 4, 1.0, 0.125)
    np.testing.assert_allclose(
        x,
        [
            0,
            0.25,
            0.5,
            0.75,
            1,
            0.75,
            0.5,
            0.25,
            0,
            0.5,
            1,
            1.5,
            2,
            1.5,
            1,
            0.5,
            0,
            0.75,
            1.5,
            2.25,
            3,
            2.25,
            1.5,
            0.75,
            0,
            1,
            2,
            3,
            4,
            3,
            2,
            1,
        ],
        atol=1e-12,
    )


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (
            dict(minimum=1.0, maximum=1.0, n_reversals=5, freq=1.0, dt=1e-3),
            "`maximum` of forc staircase must be greater than minimum = 1; got 1",
        ),
        (
            dict(minimum=0.0, maximum=1.0, n_reversals=0, freq=1.0, dt=1e-3),
            "`n_reversals` of forc staircase must be an integer >= 1; got 0",
        ),
        (
            dict(minimum=0.0, maximum=1.0, n_reversals=5, freq=1.0, dt=1e-3, shape="square"),
            "'triangle', 'cosine'; got 'square'",
        ),
        (
            dict(minimum=0.0, maximum=1.0, n_reversals=5, freq=1.0, dt=1e-3, idle=-1.0),
            "`idle` of forc staircase must be a number >= 0; got -1",
        ),
        (dict(minimum=0.0, maximum=1.0, n_reversals=5, freq=1e4, dt=1e-3), "Nyquist"),
    ],
)
def test_forc_parameter_errors(kwargs, fragment):
    with pytest.raises(SignalError, match=re.escape(fragment)):
        forc_staircase(**kwargs)


def test_forc_limits_error():
    with pytest.raises(SignalError, match=re.escape("forc staircase spans [-90, 90] but limits are [-80, 80].")):
        forc_staircase(-90.0, 90.0, 50, 20.0, 1e-4, limits=(-80.0, 80.0))


@pytest.mark.realdata
@pytest.mark.parametrize("name, freq", [("20_hz_no_lp", 20.0), ("40_hz_no_lp", 40.0), ("100_hz_no_lp", 100.0)])
def test_forc_cosine_reproduces_dspace_drive_voltage(name, freq):
    path = DSPACE / f"{name}.mat"
    if not path.exists():
        pytest.skip(f"real record absent: {path}")
    import scipy.io

    mat = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
    rec = mat[next(k for k in mat if not k.startswith("__"))]
    voltage = np.asarray(rec.Y[2].Data, dtype=float)  # Y(3): drive voltage [V]
    x = forc_staircase(-90.0, 90.0, 50, freq, 1e-4, shape="cosine", idle=1.5)
    # the record has one extra sample (its end point, back at -90 V)
    assert voltage.size == x.size + 1 and voltage[-1] == -90.0
    # the generated staircase equals the voltage dSPACE sent, to rounding (~1e-11 V)
    np.testing.assert_allclose(x, voltage[:-1], rtol=0, atol=1e-9)
    t = time_vector(x.size, 1e-4)
    assert t[-1] == pytest.approx(1.5 + 50 / freq - 1e-4)


# ----------------------------------------------------------------- regressions of the bug hunt
@pytest.mark.parametrize("make", [decaying_sine, decaying_triangle])
def test_decaying_overflow_is_refused_before_computing(make):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the old code printed an overflow RuntimeWarning first
        with pytest.raises(SignalError, match=r"beyond the largest float"):
            make(1.0, 3, 0.01, amplitude=1e308, offset=1e308)
