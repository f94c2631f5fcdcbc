"""The residual spectra the disturbance modes are read from (rules 2-3 of :mod:`.disturbance_modes`).

Every record's residual gets a Welch PSD (Hann segments, half overlap) on its own bins, with
segments long enough that its drive's harmonics are ``LINE_SPACING`` bins apart, and the bins
within ``LINE_HALF_WIDTH`` of a harmonic left out (:func:`record_spectrum`); the kept bins
are then averaged into the common grid of ``SEGMENT_SECONDS`` segments (:func:`on_common_grid`).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "LINE_SPACING",
    "LINE_HALF_WIDTH",
    "SEGMENT_SECONDS",
    "MIN_SEGMENTS",
    "segment_samples",
    "record_spectrum",
    "residual_spectra",
    "on_common_grid",
]

#: A record whose drive fundamental spans at least this many bins leaves out its harmonics ...
LINE_SPACING = 5
#: ... within this many bins.
LINE_HALF_WIDTH = 2
#: Welch segment length [s] (about 10 Hz resolution).
SEGMENT_SECONDS = 0.1
#: Fewest Welch segments (half overlap) a record needs to take part.
MIN_SEGMENTS = 4


def segment_samples(dt: float) -> int:
    """Samples of a Welch segment of about ``SEGMENT_SECONDS`` (a power of two)."""
    return int(2 ** round(np.log2(SEGMENT_SECONDS / dt)))


def record_spectrum(e: np.ndarray, u: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, int] | None:
    """``(f, P, nper)``: one residual's Welch PSD on its own bins, NaN on the bins of its drive's
    harmonics, and its segment length (rule 2); None for a record too short to take part."""
    from scipy.signal import welch

    base = segment_samples(dt)
    f0 = _fundamental(np.asarray(u, float), dt)
    # segments long enough that the harmonics are LINE_SPACING bins apart
    nper = base if f0 <= 0 else max(base, int(2 ** np.ceil(np.log2(LINE_SPACING / (f0 * dt)))))
    if e.size < nper * (MIN_SEGMENTS + 1) // 2:
        return None
    ff, p = welch(np.asarray(e, float) - np.mean(e), fs=1.0 / dt, window="hann", nperseg=nper)
    if f0 > 0:
        k = np.round(ff / f0)
        p = np.where((k >= 1) & (np.abs(ff - k * f0) <= LINE_HALF_WIDTH * (ff[1] - ff[0])), np.nan, p)
    return ff, p, nper


def residual_spectra(residuals: list[np.ndarray], drives: list[np.ndarray], dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(f, P)``: the common frequency grid and the residuals' PSDs on it, one row per record
    that takes part, NaN where a record has only harmonic bins (rules 2-3)."""
    own = [record_spectrum(e, u, dt) for e, u in zip(residuals, drives)]
    return on_common_grid([sp for sp in own if sp is not None], dt)


def on_common_grid(spectra: list, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(f, P)``: the records' own spectra averaged into the common bins (their kept bins only)."""
    f = np.fft.rfftfreq(segment_samples(dt), dt)
    df = f[1] - f[0]
    rows = []
    for ff, p, _ in spectra:
        # the mean of the kept fine bins within every common bin
        idx = np.clip(np.round(ff / df).astype(int), 0, f.size - 1)
        kept = ~np.isnan(p)
        total = np.bincount(idx[kept], p[kept], minlength=f.size)
        count = np.bincount(idx[kept], minlength=f.size)
        rows.append(np.where(count > 0, total / np.maximum(count, 1), np.nan))
    return f, np.array(rows).reshape(len(rows), f.size)


def _fundamental(u: np.ndarray, dt: float) -> float:
    """The drive's strongest frequency, from its whole-record spectrum zero-padded 8 times (the
    harmonics ``k f0`` need ``f0`` far finer than a Welch bin)."""
    n = 8 * u.size
    spec = np.abs(np.fft.rfft((u - u.mean()) * np.hanning(u.size), n))
    return float(np.argmax(spec[1:]) + 1) / (n * dt)
