"""HankelMAP runs one pipeline whatever holds the data: a chunked record goes through the same
steps, checks, warnings and diagnostics as records in memory, and ``fit`` takes it as it is."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from _chunked_data import PLANT, columns, experiment, write
from stageid._errors import ExcitationWarning, ResourceError
from stageid.data.chunked import ChunkedRecord, open_chunked
from stageid.subspace import HankelMAP
from stageid.subspace.chunked_source import fit_chunked
from stageid.subspace.statistics.chunked_statistics import range_lag_sums
from stageid.subspace.statistics.correlations import lag_correlations

N = 6007


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _record(folder, x):
    return open_chunked(write(folder, "h5", x), ["u1", "u2"], ["y1", "y2"])


def test_fit_takes_a_chunked_record(tmp_path):
    x = columns(N, seed=7)
    rec = _record(tmp_path, x)
    # a chunked record is not refined on its output error: compare with the realisation alone
    est = HankelMAP(horizon=10, order=4, band=(0.0, 450.0), output_error=False)
    got = est.fit(rec)
    on_chunks = fit_chunked(est, rec, chunk=1000)
    want = est.fit(experiment(x))
    f = np.linspace(1.0, 450.0, 40)
    # the same statistics to rounding, summed in another order: the same model to the solver's conditioning
    assert _rel(got.model.frequency_response(f), want.model.frequency_response(f)) < 1e-7
    assert _rel(on_chunks.model.frequency_response(f), want.model.frequency_response(f)) < 1e-7
    assert got.diagnostics["horizon"] == want.diagnostics["horizon"] == 10
    # the lag statistics a result keeps for its uncertainty, as the in-memory fit keeps them
    kept, ref = got.channels[0].window_lags, want.channels[0].window_lags
    assert kept is not None and kept.lags.shape == ref.lags.shape
    assert _rel(kept.lags, ref.lags) < 1e-10
    # and its result continues with new records in memory as the in-memory one does
    more = experiment(columns(3000, seed=8))
    assert _rel(got.update(more).model.frequency_response(f), want.update(more).model.frequency_response(f)) < 1e-7


def test_chunked_fit_warns_and_notes_as_in_memory(tmp_path):
    """Noise-free records make the least-squares normal equations singular: both fits warn
    with the same text and keep it in their diagnostics."""
    rng = np.random.default_rng(11)
    u = rng.standard_normal((N, 2))
    x = np.hstack([u, PLANT.simulate(u)])
    est = HankelMAP(horizon=10, order=4, method="ls", band=(0.0, 450.0))
    with pytest.warns(ExcitationWarning, match="singular"):
        want = est.fit(experiment(x))
    with pytest.warns(ExcitationWarning, match="singular"):
        got = est.fit(_record(tmp_path, x))
    assert got.diagnostics["warnings"] and got.diagnostics["warnings"] == want.diagnostics["warnings"]


def test_chunked_settings_refused_in_one_line(tmp_path):
    rec = _record(tmp_path, columns(2000, seed=1))
    with pytest.raises(ValueError, match="drop `per_channel=True`"):
        HankelMAP(horizon=5, order=2, per_channel=True).fit(rec)
    with pytest.raises(ValueError, match="forgetting is not available"):
        HankelMAP(horizon=5, order=2, forgetting=0.99).fit(rec)


def test_diagnostics_are_read_only():
    res = HankelMAP(horizon=8, order=4, band=(0.0, 450.0)).fit(experiment(columns(3000, seed=3)))
    with pytest.raises(TypeError):
        res.diagnostics["order"] = 3
    assert isinstance(res.diagnostics["warnings"], tuple)
    assert "order 4" in res.summary() and res.model.n_states == 4


def test_lag_sums_of_more_lags_than_the_last_chunk_holds(tmp_path):
    """Lags up to 4 p - 2 (the statistics a result keeps) with chunks shorter than that: the
    last chunks see fewer samples than lags."""
    x = columns(3001, seed=4)
    rec = _record(tmp_path, x)
    shift, scale = x.mean(axis=0), x.std(axis=0)
    z = (x - shift) / scale
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lags, _ = range_lag_sums(rec, [(0, 3001)], 318, shift, scale, chunk=101)
    assert _rel(lags[0], lag_correlations(z, 318)) < 1e-10


def test_a_still_input_is_noted_and_no_moving_input_refused_alike(tmp_path):
    x = columns(3000, seed=5)
    x[:, 1] = 0.3  # u2 held
    est = HankelMAP(horizon=8, order=2, band=(0.0, 450.0))
    want = est.fit(experiment(x)).diagnostics["warnings"]
    got = est.fit(_record(tmp_path, x)).diagnostics["warnings"]
    assert "input 'u2' does not move in any record; its response cannot be identified." in want
    assert got == want
    x[:, 0] = 0.3
    (tmp_path / "still").mkdir()
    with pytest.raises(ValueError, match="at least one input must move") as chunked:
        est.fit(_record(tmp_path / "still", x))
    with pytest.raises(ValueError, match="at least one input must move") as in_memory:
        est.fit(experiment(x))
    assert str(chunked.value) == str(in_memory.value)


@dataclasses.dataclass(frozen=True)
class _Unread(ChunkedRecord):
    """A chunked record that must not be read."""

    def read(self, start: int, stop: int) -> np.ndarray:
        raise AssertionError(f"read {start}..{stop}")


def test_a_chunked_record_too_large_a_horizon_is_refused_before_any_read(tmp_path):
    rec = _record(tmp_path, columns(3000, seed=6))
    unread = _Unread(**dataclasses.asdict(rec))
    with pytest.raises(ResourceError, match="horizon 20000"):
        HankelMAP(horizon=20000, order=4).fit(unread)  # about 1 TB of statistics
