"""The training / held-out split of the eq. 9 statistics (section 3.2's data for selection).

Every record is cut into interleaved training and held-out ranges (:func:`held_out_segments`);
:func:`split_statistics` gives the statistics of each group per candidate horizon (from the
whole records' lag correlations when they serve, else one pass per group of ranges), and
:func:`pooled_split` puts the two back together into the whole records' statistics without a
second pass over long records.  A smaller horizon's statistics come from a larger one's blocks
(:func:`central_statistics`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..statistics.correlations import RecordRows, input_periodogram, lag_correlations, range_ends, straddling_lags
from ..statistics.hankel_toeplitz import WindowStatistics, lag_statistics, record_statistics, segments_statistics
from ..statistics.window_covariance import WindowLags

__all__ = ["MIN_SEGMENT", "held_out_segments", "central_statistics", "split_statistics", "pooled_split"]

#: Shortest held-out segment, in samples: records are cut into at most ``n / (8 MIN_SEGMENT)`` segments.
MIN_SEGMENT = 20


def held_out_segments(n: int, validation_fraction: float) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Training and held-out sample ranges of one record of ``n`` samples (interleaved).

    ``k = n // (8 MIN_SEGMENT)`` equal segments, at least 4 and at most 32, of which
    ``round(validation_fraction k)`` spread evenly over the record are held out; adjacent
    segments of one kind are merged into one range.
    """
    k = int(max(4, min(32, n // max(8 * MIN_SEGMENT, 1))))
    n_val = max(1, int(round(validation_fraction * k)))
    val_idx = sorted({int(np.floor((i + 0.5) * k / n_val)) % k for i in range(n_val)})
    edges = [int(round(i * n / k)) for i in range(k + 1)]
    train, val = [], []
    for i in range(k):
        rng = (edges[i], edges[i + 1])
        target = val if i in val_idx else train
        if target and target[-1][1] == rng[0]:
            target[-1] = (target[-1][0], rng[1])
        else:
            target.append(rng)
    return train, val


def by_largest_horizon(ranges: Sequence[tuple[int, int]], cands: list[int]) -> dict[int, list[int]]:
    """The ranges (their indices) grouped by the largest candidate horizon each holds
    (``2 p + 1`` samples); a range too short for every candidate is in no group."""
    groups: dict[int, list[int]] = {}
    for i, (a, b) in enumerate(ranges):
        usable = [p for p in cands if 2 * p + 1 <= b - a]
        if usable:
            groups.setdefault(usable[-1], []).append(i)
    return groups


def add_leading(target: dict[int, WindowStatistics], top: WindowStatistics, cands: list[int]) -> None:
    """Add ``top``'s statistics to ``target`` at every candidate up to its horizon: smaller
    horizons use its leading block (exact statistics over a slightly smaller window set)."""
    for p in (p for p in cands if p <= top.horizon):
        sp = top if p == top.horizon else top.leading(p)
        target[p] = sp if p not in target else target[p] + sp


def central_statistics(stats: WindowStatistics, horizon: int) -> WindowStatistics:
    """Statistics of horizon ``horizon`` from those of a larger one ``P``: its central block, the
    window positions ``P - horizon .. P + horizon - 1`` (the larger one's windows, predicting
    from the same point, so that the candidates' regressions are nested: :mod:`.nested_horizons`)."""
    if horizon == stats.horizon:
        return stats
    r = stats.n_inputs + stats.n_outputs
    a, b = (stats.horizon - horizon) * r, (stats.horizon + horizon) * r
    return WindowStatistics(
        stats.W[a:b, a:b], stats.n_windows, horizon, stats.n_inputs, stats.n_outputs, None, None, stats.count
    )


def split_statistics(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    cands: list[int],
    forgetting: float,
    validation_fraction: float,
    whole: WindowLags | None = None,
) -> tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]]:
    """Eq. 9 statistics of the training and of the held-out segments, per candidate horizon.

    One Gram matrix per segment at its largest usable horizon, summed per horizon; smaller
    horizons use its leading block (exact statistics over a slightly smaller window set).
    The training windows are weighted by ``forgetting`` (each range as a record of its own).
    Given the whole records' lag correlations (``whole``, at a horizon of at least the largest
    candidate), when every range holds the largest candidate and there is no forgetting, the
    training segments' lag correlations are the whole records' less the held-out segments'
    and the products straddling the range boundaries (:func:`_split_from_whole`): no FFT pass
    over the training segments.
    """
    train: dict[int, WindowStatistics] = {}
    val: dict[int, WindowStatistics] = {}
    top = max(cands)
    splits = [held_out_segments(u.shape[0], validation_fraction) for u, _ in records]
    every_range_holds_top = all(b - a >= 2 * top + 1 for tr, va in splits for a, b in tr + va)
    if whole is not None and forgetting == 1.0 and whole.horizon >= top and every_range_holds_top:
        t, v = _split_from_whole(records, splits, top, whole)
        tops: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({top: t}, {top: v})
    else:
        tops = _split_tops(records, splits, cands, forgetting)
    for acc, target in zip(tops, (train, val)):
        for stats in acc.values():
            add_leading(target, stats, cands)
    return train, val


def _split_from_whole(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    splits: list[tuple[list[tuple[int, int]], list[tuple[int, int]]]],
    horizon: int,
    whole: WindowLags,
) -> tuple[WindowStatistics, WindowStatistics]:
    """Training and held-out statistics at ``horizon``, every range holding it: the held-out
    lag correlations from one pass over the held-out ranges, the training ones as the whole
    records' less those and the products straddling the range boundaries (each such pair
    joins two neighbouring ranges, the ranges being longer than the largest lag); exact to
    rounding."""
    L = 2 * horizon
    m = records[0][0].shape[1]
    R_val = np.zeros((L,) + whole.lags.shape[1:])
    ends: list[list[np.ndarray]] = [[], [], [], []]  # training heads, tails, held-out heads, tails
    joints: list[list[np.ndarray]] = [[], []]  # the L - 1 samples before and after every boundary
    for (u, y), (tr, va) in zip(records, splits):
        R_val += lag_correlations(RecordRows([u, y], va, gap=L), L - 1)
        for i, ranges in enumerate((tr, va)):
            for k, part in enumerate(range_ends(u, y, ranges, L)):
                ends[2 * i + k].append(part)
        cuts = sorted(b for _, b in tr + va)[:-1]
        if cuts:
            for k, part in enumerate(range_ends(u, y, [(c - L + 1, c + L - 1) for c in cuts], L - 1)):
                joints[k].append(part)
    R_train = whole.lags[:L] - R_val
    if joints[0]:
        R_train -= straddling_lags(np.concatenate(joints[0]), np.concatenate(joints[1]))
    out = []
    for i, R in enumerate((R_train, R_val)):
        count = sum(b - a - L + 1 for split in splits for a, b in split[i])
        out.append(lag_statistics(R, np.concatenate(ends[2 * i]), np.concatenate(ends[2 * i + 1]), count, m))
    return out[0], out[1]


def _split_tops(
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    splits: list[tuple[list[tuple[int, int]], list[tuple[int, int]]]],
    cands: list[int],
    forgetting: float,
) -> tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]]:
    """Training and held-out statistics per largest usable horizon of their ranges, one pass
    over each group of ranges (with forgetting, one per range)."""
    tops: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({}, {})
    for (u, y), (tr, va) in zip(records, splits):
        for ranges, acc, weight in ((tr, tops[0], forgetting), (va, tops[1], 1.0)):
            for ph, idx in by_largest_horizon(ranges, cands).items():
                rngs = [ranges[i] for i in idx]
                if weight == 1.0:
                    tops_ = [segments_statistics(u, y, rngs, ph)]
                else:  # forgetting: each range weighted on its own, as a record of its own
                    tops_ = [record_statistics(u[a:b], y[a:b], [ph], weight, with_spectrum=False)[ph] for a, b in rngs]
                for top in tops_:
                    acc[ph] = top if ph not in acc else acc[ph] + top
    return tops


def pooled_split(
    train: dict[int, WindowStatistics],
    val: dict[int, WindowStatistics],
    horizon: int,
    records: Sequence[tuple[np.ndarray, np.ndarray]],
    validation_fraction: float,
    whole: WindowLags | None = None,
) -> WindowStatistics | None:
    """The whole records' eq. 9 statistics (not forgetting), with their input spectrum: from
    their lag correlations ``whole`` when given (at a horizon of at least ``horizon``), else
    completed from the held-out split; None when the split cannot be completed cheaply.

    The split lacks the windows that straddle segment boundaries and, for horizons below a
    range's largest usable one, the last windows of each range (see :func:`split_statistics`);
    those are added from one :func:`segments_statistics` pass over short sample ranges around
    the range ends.  Either way the result equals the statistics of the whole records up to
    rounding and saves a second pass over long records.
    """
    if whole is not None and whole.horizon >= horizon:
        s = whole.statistics(horizon, records[0][0].shape[1])
        return WindowStatistics(s.W, s.n_windows, horizon, s.n_inputs, s.n_outputs, *_periodogram(records), s.count)
    if horizon not in train or horizon not in val:
        return None
    keys = sorted(set(train) | set(val))
    t, v = train[horizon], val[horizon]
    W = t.W + v.W  # a fresh matrix: the missing windows are added in place (no further copies)
    n_windows, count = t.n_windows + v.n_windows, t.count + v.count
    for u, y in records:
        missing = _missing_ranges(u.shape[0], keys, horizon, validation_fraction)
        if missing is None:
            return None
        if missing:
            extra = segments_statistics(u, y, missing, horizon)
            W += extra.W
            n_windows, count = n_windows + extra.n_windows, count + extra.count
    if count != sum(u.shape[0] - 2 * horizon + 1 for u, _ in records):
        return None
    return WindowStatistics(W, n_windows, horizon, t.n_inputs, t.n_outputs, *_periodogram(records), count)


def _periodogram(records: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The records' input periodograms, summed (:func:`~stageid.subspace.statistics.correlations.input_periodogram`)."""
    power, freqs = input_periodogram(records[0][0])
    for u, _ in records[1:]:
        power = power + input_periodogram(u)[0]
    return power, freqs


def _missing_ranges(n: int, keys: list[int], horizon: int, validation_fraction: float) -> list[tuple[int, int]] | None:
    """Sample ranges holding exactly the horizon-``horizon`` windows of one record that
    :func:`split_statistics` left out; None when they overlap or hold a single window (then
    :func:`segments_statistics` cannot take them)."""
    tr, va = held_out_segments(n, validation_fraction)
    covered = []  # window starts [first, last] each range contributed at its largest usable horizon
    for a, b in sorted(tr + va):
        tops = [k for k in keys if 2 * k + 1 <= b - a]
        if tops and tops[-1] >= horizon:
            covered.append((a, b - 2 * tops[-1]))
    gaps, nxt = [], 0
    for first, last in covered + [(n - 2 * horizon + 1, None)]:
        if first > nxt:
            gaps.append((nxt, first - 1))
        nxt = nxt if last is None else last + 1
    ranges = [(s0, s1 + 2 * horizon) for s0, s1 in gaps]
    if any(s1 == s0 for s0, s1 in gaps) or any(b0 > a1 for (_, b0), (a1, _) in zip(ranges, ranges[1:])):
        return None
    return ranges
