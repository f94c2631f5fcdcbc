"""Preprocessing: offset/trend removal, split, merge, decimate."""

from __future__ import annotations

import numpy as np
import pytest

from stageid import DataError
from stageid.data import Experiment, Offsets, decimate, merge, remove_offset, split


def _exp(n=200, dt=0.01, t0=0.0, seed=0, **kw) -> Experiment:
    rng = np.random.default_rng(seed)
    return Experiment(
        u=rng.standard_normal((n, 2)) + [1.0, -2.0], y=rng.standard_normal((n, 1)) + 5.0, dt=dt, t0=t0, **kw
    )


# ----------------------------------------------------------------- remove_offset
def test_constant_offset_removed_and_restorable():
    exp = _exp()
    centred, offsets = remove_offset(exp)
    assert isinstance(offsets, Offsets) and offsets.kind == "constant"
    # means of 200 samples sum rounding: 1e-12 is far below any physical offset
    assert np.allclose(centred.u.mean(axis=0), 0.0, atol=1e-12)
    assert np.allclose(centred.y.mean(axis=0), 0.0, atol=1e-12)
    assert np.allclose(offsets.input_offset, exp.u.mean(axis=0), rtol=0, atol=1e-14)
    assert np.array_equal(offsets.input_slope, [0.0, 0.0])
    back = offsets.restore(centred)
    assert np.allclose(back.u, exp.u, rtol=0, atol=1e-12) and np.allclose(back.y, exp.y, rtol=0, atol=1e-12)
    assert centred.input_names == exp.input_names and centred.dt == exp.dt


def test_channels_option_leaves_the_others_untouched():
    exp = _exp()
    only_out, off = remove_offset(exp, channels="outputs")
    assert np.array_equal(only_out.u, exp.u)
    assert np.array_equal(off.input_offset, [0.0, 0.0])
    only_in, off = remove_offset(exp, channels="inputs")
    assert np.array_equal(only_in.y, exp.y)
    assert np.array_equal(off.output_offset, [0.0])


def test_linear_trend_recovered_exactly_with_nonzero_t0():
    t0, dt, n = 3.0, 0.5, 40
    time = t0 + dt * np.arange(n)
    u = np.column_stack([1.0 + 0.2 * (time - t0), -4.0 - 0.1 * (time - t0)])
    y = (7.0 + 2.0 * (time - t0))[:, None]
    exp = Experiment(u=u, y=y, dt=dt, t0=t0)
    flat, off = remove_offset(exp, kind="linear")
    # exact straight lines: the least-squares fit leaves only rounding (values are O(10))
    assert np.allclose(flat.u, 0.0, atol=1e-12) and np.allclose(flat.y, 0.0, atol=1e-12)
    assert np.allclose(off.input_offset, [1.0, -4.0], atol=1e-12)
    assert np.allclose(off.input_slope, [0.2, -0.1], atol=1e-12)
    assert np.allclose(off.output_slope, [2.0], atol=1e-12)
    assert off.t_ref == t0


def test_offsets_applied_to_a_continuation_match_detrending_the_whole():
    exp = _exp(n=300)
    first, rest = exp.slice(0, 200), exp.slice(200, 300)
    flat_first, off = remove_offset(first, kind="linear")
    whole = off.remove(exp)
    assert np.allclose(whole.slice(0, 200).y, flat_first.y, atol=1e-12)
    u_tr, y_tr = off.trend(rest)
    assert np.allclose(off.remove(rest).y, rest.y - y_tr, atol=1e-12)
    with pytest.raises(DataError, match=r"fitted on 2 inputs / 1 outputs; got an experiment with 1 / 1"):
        off.remove(Experiment(u=np.zeros(5), y=np.zeros(5), dt=0.01))


def test_remove_offset_errors_and_no_mutation():
    exp = _exp(n=50)
    u_before = exp.u.copy()
    with pytest.raises(DataError, match=r"`kind` must be one of 'constant', 'linear'; got 'quadratic'"):
        remove_offset(exp, kind="quadratic")
    with pytest.raises(DataError, match=r"`channels` must be one of 'both', 'inputs', 'outputs'; got 'all'"):
        remove_offset(exp, channels="all")
    with pytest.raises(DataError, match=r"at least 2 samples"):
        remove_offset(exp.slice(0, 1), kind="linear")
    with pytest.raises(DataError, match=r"must be an Experiment"):
        remove_offset(np.zeros((5, 2)))
    remove_offset(exp, kind="linear")
    assert np.array_equal(exp.u, u_before)


# ----------------------------------------------------------------- split
def test_split_sizes_continuity_and_time():
    exp = _exp(n=101, dt=0.1, t0=1.0)
    train, val = split(exp, 0.75)
    assert (train.n_samples, val.n_samples) == (76, 25)  # round(75.75) = 76
    assert np.array_equal(np.vstack([train.y, val.y]), exp.y)
    assert val.t0 == pytest.approx(1.0 + 76 * 0.1, rel=1e-12)
    assert train.name == exp.name == val.name


@pytest.mark.parametrize("fraction", [0.0, 1.0, 1.5, -0.2, float("nan"), "half"])
def test_split_rejects_bad_fractions(fraction):
    with pytest.raises(DataError, match=r"`fraction` must be a number between 0 and 1"):
        split(_exp(n=20), fraction)


def test_split_rejects_too_short_parts():
    with pytest.raises(DataError, match=r"gives parts of 10 and 0 samples; each part needs at least 2"):
        split(_exp(n=10), 0.99)
    with pytest.raises(DataError, match=r"parts of 7 and 3 samples; each part needs at least 5"):
        split(_exp(n=10), 0.7, min_samples=5)
    train, val = split(_exp(n=4), 0.5)
    assert train.n_samples == val.n_samples == 2


# ----------------------------------------------------------------- merge
def test_merge_checks_sample_time_names_and_units():
    a = _exp(seed=1, input_units=("V", "V"), output_units=("um",))
    b = _exp(seed=2, n=150, input_units=("V", "V"), output_units=("um",))
    merged = merge([a, b])
    assert merged == (a, b)
    assert merge(a) == (a,)
    with pytest.raises(DataError, match=r"one sample time"):
        merge([a, _exp(dt=0.02)])
    with pytest.raises(DataError, match=r"same channels"):
        merge([a, a.with_(output_names=("z",))])
    with pytest.raises(
        DataError,
        match=r"same units; got inputs \['V', 'V'\] / outputs \['um'\] and inputs \['V', 'V'\] / outputs \['nm'\]",
    ):
        merge([a, a.with_(output_units=("nm",))])
    with pytest.raises(DataError, match=r"at least one experiment"):
        merge([])


# ----------------------------------------------------------------- decimate
def test_decimate_keeps_low_and_removes_high_frequencies():
    dt, n, q = 1e-3, 4000, 10
    time = dt * np.arange(n)
    low = np.sin(2 * np.pi * 5.0 * time)  # 5 Hz, well inside the new 50 Hz Nyquist band
    high = np.sin(2 * np.pi * 180.0 * time)  # above the new Nyquist: must not alias
    exp = Experiment(u=low + high, y=low, dt=dt)
    slow = decimate(exp, q)
    assert slow.n_samples == 400 and slow.dt == pytest.approx(q * dt, rel=1e-15)
    inner = slice(20, -20)  # skip filter edge effects
    ref = low[::q][inner]
    # the FIR anti-alias filter passes 5 Hz with < 1 % error and damps 180 Hz below 2 %
    assert np.max(np.abs(slow.y[inner, 0] - ref)) < 1e-2
    assert np.max(np.abs(slow.u[inner, 0] - ref)) < 2e-2
    naive = decimate(exp, q, antialias=False)
    assert np.array_equal(naive.u[:, 0], (low + high)[::q])
    # picking samples aliases 180 Hz to 20 Hz at full amplitude: what the filter prevents
    assert np.max(np.abs(naive.u[inner, 0] - ref)) > 0.5


def test_decimate_errors_and_identity():
    exp = _exp(n=50)
    assert np.array_equal(decimate(exp, 1).u, exp.u)
    for bad in (0, -2, 1.5, True):
        with pytest.raises(DataError, match=r"`factor` must be a positive integer"):
            decimate(exp, bad)
    with pytest.raises(DataError, match=r"needs at least 101 samples; got 50"):
        decimate(exp, 5)
    assert decimate(exp, 5, antialias=False).n_samples == 10


def test_decimate_passes_constants_unchanged_up_to_the_edges():
    # regression: zero padding at the ends pulled a constant down to 0.667 at the first sample
    slow = decimate(Experiment(u=np.ones(300), y=np.full(300, -4.0), dt=0.1), 3)
    assert slow.n_samples == 100
    # a unit-DC-gain FIR on a constant: only rounding of the convolution remains
    np.testing.assert_allclose(slow.u[:, 0], 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(slow.y[:, 0], -4.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("freq", [0.5, 2.0])
def test_decimate_slow_sine_has_no_edge_transient(freq):
    dt, n, q = 1e-3, 3000, 5
    x = 3.0 + np.sin(2 * np.pi * freq * dt * np.arange(n) + 0.3)  # far below the new 100 Hz Nyquist
    slow = decimate(Experiment(u=x, y=2.0 * x, dt=dt), q)
    err = np.abs(slow.u[:, 0] - x[::q])
    # Hamming-window passband ripple is ~1e-3 at most; the edges must be no worse than the
    # interior (the old zero-padded filter was off by 0.1-1 there)
    assert np.max(err) < 1e-3
    assert max(err[:10].max(), err[-10:].max()) <= 2 * err[10:-10].max() + 1e-9
    np.testing.assert_allclose(slow.y[:, 0], 2.0 * slow.u[:, 0], rtol=1e-12)
