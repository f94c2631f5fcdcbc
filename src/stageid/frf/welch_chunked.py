"""Welch's spectra of a record larger than memory: segment sums chunk by chunk, then reduced.

The spectra of :func:`~.welch.cross_spectra` are a sum over segments ``k`` starting at
``k step``.  A task takes the segments ``k0 .. k1 - 1`` and reads the samples
``k0 step .. (k1 - 1) step + segment`` (so the segment overlap at chunk borders is read twice,
never lost), sums ``conj(X) X^T`` over them with :func:`~.welch.segment_sums`, and the sums
are added: the result equals the in-memory spectra to rounding.  The last task also reads the
samples after the last segment, so every sample is checked to be finite.  With a
``dask.distributed`` client the tasks run on its workers (each reads its own range).
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError
from ..checks import check_integer, check_real
from ..data.chunked import DEFAULT_CHUNK, ChunkedRecord, check_finite_rows, map_reduce
from ..models.frequency_response import FrequencyResponse
from .records import ChannelRecord
from .welch import CrossSpectra, default_segment, get_window, h1_from_spectra, segment_sums, spectra_from_sums

__all__ = ["chunked_cross_spectra", "chunked_welch_frf"]


def _segments_task(record: ChunkedRecord, k0: int, k1: int, step: int, w: np.ndarray, last: bool) -> np.ndarray:
    a = k0 * step
    b = record.n_samples if last else (k1 - 1) * step + w.size
    x = record.read(a, b)
    check_finite_rows(x, record.names, a, record.name)
    chunk = ChannelRecord(tuple(x[:, j] for j in range(x.shape[1])), record.n_inputs, record.dt, (), ())
    acc, count = segment_sums(chunk, w, step)
    if count != k1 - k0:  # the read range holds exactly these segments; anything else is a bug
        raise DataError(f"internal: {count} segments read for {k1 - k0} in samples {a}..{b}.")
    return acc


def chunked_cross_spectra(
    record: ChunkedRecord,
    segment: int,
    overlap: float = 0.5,
    window: str = "hann",
    chunk: int = DEFAULT_CHUNK,
    client=None,
) -> CrossSpectra:
    """:func:`~.welch.cross_spectra` of a chunked record, about ``chunk`` samples per task.

    Raises
    ------
    DataError
        A record shorter than one segment, a NaN or inf sample.
    """
    segment = check_integer(segment, "segment", "welch_frf", low=2)
    overlap = check_real(overlap, "overlap", "welch_frf", low=0.0, high=1.0, closed="left")
    w = get_window(window, segment)
    step = segment - int(overlap * segment)
    n = record.n_samples
    if n < segment:
        raise DataError(
            f"record '{record.name or 'data'}' has {n} samples, fewer than one segment of {segment}; "
            "give a shorter `segment=`."
        )
    n_seg = (n - segment) // step + 1
    per_task = max(1, chunk // step)
    bounds = list(range(0, n_seg, per_task)) + [n_seg]
    args = [(record, k0, k1, step, w, k1 == n_seg) for k0, k1 in zip(bounds[:-1], bounds[1:])]
    acc = map_reduce(_segments_task, args, lambda total, _, a: a if total is None else total + a, client)
    return spectra_from_sums(acc, [n_seg], w, step, record.dt, record.n_inputs)


def chunked_welch_frf(
    record: ChunkedRecord,
    segment: int | None = None,
    overlap: float = 0.5,
    window: str = "hann",
    chunk: int = DEFAULT_CHUNK,
    client=None,
) -> FrequencyResponse:
    """:func:`~.welch.welch_frf` of a chunked record (segment default :func:`~.welch.default_segment`)."""
    if segment is None:
        segment = default_segment(record.n_samples)
    spectra = chunked_cross_spectra(record, segment, overlap, window, chunk, client)
    return h1_from_spectra(spectra, record.input_names, record.output_names)
