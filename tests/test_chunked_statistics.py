"""Chunked records: the eq. 9 statistics, the held-out split, Welch's spectra and the identified
model equal the in-memory ones, whatever the chunk length (also chunks shorter than a window)."""

from __future__ import annotations

import numpy as np
import pytest

from _chunked_data import DT, columns, experiment, write
from stageid.data.chunked import open_chunked
from stageid.frf.welch import cross_spectra, welch_frf
from stageid.frf.welch_chunked import chunked_cross_spectra, chunked_welch_frf
from stageid.subspace.chunked_source import ChunkedSource, chunked_split_statistics, fit_chunked
from stageid.subspace.estimator import HankelMAP
from stageid.subspace.records import channel_scales, prepared_records, to_unit_rms
from stageid.subspace.selection import held_out_segments, horizon_candidates, split_statistics
from stageid.subspace.statistics.chunked_statistics import column_moments, range_lag_sums, ranged_statistics
from stageid.subspace.statistics.hankel_toeplitz import segments_statistics, window_statistics

N = 12_011  # prime: no chunk length below divides it
#: 1e-10 relative is the issue's bar; sums of 10^4 products in another order differ by ~1e-15
RTOL = 1e-10
#: chunk lengths: the whole record, not dividing N, and shorter than the largest window of the
#: horizon selection (2 x 80); chunks shorter than the window 2p of the statistics (1 .. 7 samples)
#: run on a short record in test_short_chunks (each task reads the file: h5py takes ~1 ms a read)
CHUNKS = [N, 4096, 1001, 97]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    x = columns(N)
    path = write(tmp_path_factory.mktemp("rec"), "h5", x)
    return x, open_chunked(path, ["u1", "u2"], ["y1", "y2"])


def _scaled_in_memory(x):
    recs = prepared_records([experiment(x)], detrend=True)
    su, sy = to_unit_rms(recs, None)
    return recs[0], np.concatenate([su, sy])


@pytest.mark.parametrize("chunk", CHUNKS)
def test_moments_and_scales_equal_in_memory(data, chunk):
    x, rec = data
    mom = column_moments(rec, chunk)
    assert mom.count == N
    np.testing.assert_allclose(mom.mean, x.mean(axis=0), rtol=1e-13)
    recs = prepared_records([experiment(x)], detrend=True)
    su, sy = channel_scales(recs)
    np.testing.assert_allclose(mom.rms, np.concatenate([su, sy]), rtol=1e-12)
    np.testing.assert_array_equal(mom.low, x.min(axis=0))
    np.testing.assert_array_equal(mom.high, x.max(axis=0))


@pytest.mark.parametrize("chunk", CHUNKS)
def test_window_statistics_equal_in_memory(data, chunk):
    x, rec = data
    (u, y), scale = _scaled_in_memory(x)
    shift = x.mean(axis=0)
    p = 6
    lags, power = range_lag_sums(rec, [(0, N)], 2 * p - 1, shift, scale, chunk, spectrum=True)
    got = ranged_statistics(rec, [(0, N)], lags, p, shift, scale)
    want = window_statistics(u, y, p)
    assert got.count == want.count and got.n_windows == want.n_windows
    assert _rel(got.W, want.W) < RTOL
    assert power.shape == want.input_power.shape
    # several ranges (held-out segments) at once, each with its own history limit
    ranges = [(0, 3000), (3000, 3013), (5000, 9100), (9100, N)]
    lags, _ = range_lag_sums(rec, ranges, 2 * p - 1, shift, scale, chunk)
    assert _rel(ranged_statistics(rec, ranges, lags, p, shift, scale).W, segments_statistics(u, y, ranges, p).W) < RTOL


@pytest.mark.parametrize("chunk", [4096, 97])
def test_held_out_split_equals_in_memory(data, chunk):
    x, rec = data
    (u, y), scale = _scaled_in_memory(x)
    cands = horizon_candidates(2, 2, [N])
    train, val = chunked_split_statistics(ChunkedSource(rec, x.mean(axis=0), scale, chunk), cands, 0.25)
    want_train, want_val = split_statistics([(u, y)], cands, 1.0, 0.25)
    assert set(train) == set(want_train) and set(val) == set(want_val) and train
    for p in train:
        assert train[p].count == want_train[p].count
        assert _rel(train[p].W, want_train[p].W) < RTOL
        assert _rel(val[p].W, want_val[p].W) < RTOL
    assert len(held_out_segments(N, 0.25)[1]) >= 1


def test_short_chunks(tmp_path):
    """Chunks of 1 .. 7 samples, shorter than the window (2p = 10) and than Welch's overlap (32)."""
    x = columns(301, seed=2)
    rec = open_chunked(write(tmp_path, "h5", x), ["u1", "u2"], ["y1", "y2"])
    (u, y), scale = _scaled_in_memory(x)
    for chunk in (1, 2, 3, 7):
        lags, _ = range_lag_sums(rec, [(0, 301)], 9, x.mean(axis=0), scale, chunk)
        got = ranged_statistics(rec, [(0, 301)], lags, 5, x.mean(axis=0), scale)
        assert _rel(got.W, window_statistics(u, y, 5).W) < RTOL
        spectra = chunked_cross_spectra(rec, 64, 0.5, chunk=chunk)
        assert _rel(spectra.S, cross_spectra(experiment(x), 64, 0.5).S) < RTOL


def test_block_periodogram_finds_about_the_in_memory_band(tmp_path):
    """Without ``band`` the excited band comes from 1024-sample blocks, not from the record's own
    FFT: an estimate of the same binned spectrum, whose 1 % crossing on a filter's slope moves
    by a few bins with the estimate's variance (5 bins here: 0.5 % of the sample rate)."""
    rng = np.random.default_rng(3)
    n = 40_000
    from scipy.signal import butter, sosfilt

    u = sosfilt(butter(6, 0.2, output="sos"), rng.standard_normal((n, 2)), axis=0)  # 0-100 Hz of 500
    x = np.hstack([u, u @ [[1.0, 0.2], [0.1, 1.0]] + 0.01 * rng.standard_normal((n, 2))])
    rec = open_chunked(write(tmp_path, "h5", x), ["u1", "u2"], ["y1", "y2"])
    est = HankelMAP(horizon=8, order=2, refine=False)
    got = fit_chunked(est, rec, chunk=5000).diagnostics["band_hz"]
    want = est.fit(experiment(x)).diagnostics["band_hz"]
    bin_hz = 1.0 / (1024 * DT)
    assert got[0] == want[0] == 0.0
    assert abs(got[1] - want[1]) <= 5 * bin_hz
    assert 100.0 < got[1] < 200.0  # past the filter's corner, far below Nyquist (500 Hz)


@pytest.mark.parametrize("horizon", [10, "auto"])
def test_identified_model_matches_in_memory(data, horizon):
    x, rec = data
    est = HankelMAP(horizon=horizon, order=4, band=(0.0, 450.0), output_error=False)  # chunked: not refined
    want = est.fit(experiment(x))
    for chunk in (5003, 101):
        got = fit_chunked(est, rec, chunk=chunk)
        assert got.diagnostics["horizon"] == want.diagnostics["horizon"]
        f = np.linspace(1.0, 450.0, 60)
        # the same statistics to ~1e-15 give the same model to the solver's conditioning
        assert _rel(got.model.frequency_response(f), want.model.frequency_response(f)) < 1e-7
        np.testing.assert_allclose(np.sort(np.abs(got.model.poles())), np.sort(np.abs(want.model.poles())), rtol=1e-8)
        assert got.model.inputs == ("u1", "u2") and got.model.outputs == ("y1", "y2")
    if horizon == "auto":
        assert got.channels[0].horizon_table.errors == pytest.approx(want.channels[0].horizon_table.errors, rel=1e-8)


@pytest.mark.parametrize("horizon", [10, "auto"])
def test_order_selection_matches_in_memory(data, horizon):
    """order="auto": the held-out simulation errors of one sequential pass, state carried across chunks."""
    x, rec = data
    est = HankelMAP(horizon=horizon, order="auto", max_order=6, band=(0.0, 450.0), output_error=False)
    want = est.fit(experiment(x))
    got = fit_chunked(est, rec, chunk=2999)
    assert got.diagnostics["order"] == want.diagnostics["order"] == 4
    table, ref = got.channels[0].order_table, want.channels[0].order_table
    assert table.values == ref.values
    np.testing.assert_allclose(table.errors, ref.errors, rtol=1e-8)


@pytest.mark.parametrize("segment, overlap", [(1024, 0.5), (1000, 0.3), (256, 0.0)])
def test_welch_spectra_equal_in_memory(data, segment, overlap):
    x, rec = data
    want = cross_spectra(experiment(x), segment, overlap)
    for chunk in (N, 3001, 100, 1):  # 100 and 1: shorter than a segment and its overlap
        got = chunked_cross_spectra(rec, segment, overlap, chunk=chunk)
        assert got.n_segments == want.n_segments and got.effective_segments == want.effective_segments
        assert _rel(got.S, want.S) < RTOL
    frd = chunked_welch_frf(rec, segment, overlap, chunk=777)
    ref = welch_frf(experiment(x), segment, overlap)
    assert _rel(frd.response, ref.response) < RTOL


@pytest.mark.parametrize("fmt", ["h5", "h5-t", "zarr", "npy-folder", "npy"])
def test_every_format_gives_the_same_statistics(tmp_path, fmt):
    x = columns(3000, seed=1)
    path = write(tmp_path, fmt, x)
    names = (["rec_1", "rec_2"], ["rec_3", "rec_4"]) if fmt == "npy" else (["u1", "u2"], ["y1", "y2"])
    rec = open_chunked(path, *names, ts=DT if fmt == "npy" else None)
    assert rec.n_samples == 3000 and rec.dt == pytest.approx(DT, rel=1e-9)
    np.testing.assert_array_equal(rec.read(123, 456), x[123:456])
    (u, y), scale = _scaled_in_memory(x)
    lags, _ = range_lag_sums(rec, [(0, 3000)], 7, x.mean(axis=0), scale, 700)
    assert (
        _rel(ranged_statistics(rec, [(0, 3000)], lags, 4, x.mean(axis=0), scale).W, window_statistics(u, y, 4).W) < RTOL
    )
