"""Lightly damped modes of a stage from the disturbance in its identification records.

A piezo stage's mechanical mode is rung by broadband disturbances (amplifier noise, floor
vibration) that enter *before* the dynamics, so the mode shows in the output noise of records
whose drive carries no power near it: the noise shares the plant's denominator (the ARMAX view
of a prediction-error method).  Under the stage model's structure (unit-DC-gain dynamics after
the hysteresis and creep) a resonance without nearby zeros is fixed by its frequency and
damping, which the residual spectrum gives.  :func:`disturbance_modes` finds them;
:func:`resonance_filter` turns them into a unit-DC-gain filter that the stage identification
puts in series with its low-order dynamics (:mod:`.stage_identification`).

**Decision rule** (fixed from the FORC identification records and simulation only; the
tracking records are validation data and did not set it):

1. Residual ``e_j`` of the current stage fit on every record ``j`` (own offset and start).
   Which fits' residuals are searched is :mod:`.mode_proposals`' choice.
2. Welch PSD of every residual, Hann segments, half overlap, on a common grid of
   ``SEGMENT_SECONDS`` bins (a power of two samples; 1024 at 10 kHz, about 10 Hz).  A record's
   segments are longer when its drive fundamental ``f0`` (the largest peak of the drive's
   spectrum) is closer than ``LINE_SPACING`` common bins, so that its harmonics are always at
   least ``LINE_SPACING`` of its own bins apart (4096 samples for a 20 Hz drive at 10 kHz).
   A record shorter than ``MIN_SEGMENTS`` of its segments takes no part; with none left there
   is no mode.
3. The detection spectrum is the **bin-wise minimum** over the records' PSDs: a stationary
   disturbance rings the mode in every record at the same level, while harmonics of one
   record's drive (model error) sit at that record's own frequencies and do not survive the
   minimum.  So a mode must stand in every record (agreement between records).  Harmonics
   common to several records (200 Hz of a 20 Hz and a 100 Hz drive) would survive it, so
   every record leaves out its bins within ``LINE_HALF_WIDTH`` of its own bins of ``k f0``
   and averages the rest into the common bins.  Only common bins that every record keeps are
   candidates and are fitted (elsewhere a line of one record would stand alone); the others
   are interpolated from their neighbours for the floor.
4. The floor at frequency ``f`` is the median of the detection spectrum over ``[f/2, 2f]``,
   and never below the numerical floor: the PSD of white noise of RMS ``PRECISION_ULPS``
   rounding units of the records' largest output (``output_scale``), so a residual at the
   level of floating-point rounding (a noise-free record the model holds) never yields a mode.
   Candidates are local maxima in ``[BAND[0], BAND[1]] * fs`` whose ratio to the floor is at
   least ``CANDIDATE_RATIO``, strongest first, at most ``MAX_MODES`` accepted.
5. Each candidate's spectrum over ``[f/SPAN, f*SPAN]`` is fitted (log least squares, robust
   loss) by ``floor + K |R(f)|^2``, ``R`` the unit-gain second-order resonance, with ``|R|^2``
   convolved with the Hann window's kernel (the expected Welch estimate).  The candidate is a
   **mode** when the fitted peak over the floor is at least ``PEAK_RATIO``, the damping is at
   most ``MAX_DAMPING`` (lightly damped), and the half-power width ``2 zeta fn`` is at least one
   bin (narrower is a periodic line, not a mode rung by broadband noise; when the fit puts
   such a line on the candidate's own bin, ``SEPARATION`` bins either side of it are its
   window's leakage and give no mode).
6. A candidate within ``SEPARATION`` half-power half-widths (``zeta fn``) of an accepted
   mode is not added (its shoulder); nor one within ``SEPARATION`` times the larger of its
   own damping and ``min(zeta_p, MAX_DAMPING)`` (relative) of a complex pole pair of the
   current dynamics with damping ``zeta_p < POLE_DAMPING`` (a resonance the input-output
   fit already has, even a little more damped than a mode; added after the validation figures,
   changes none of them: the real records' fits have no complex poles).
7. A mode's frequency and damping are then fitted to every record's own spectrum at once (its
   own bins, harmonics left out): one resonance and one ring level common to all records (a
   stationary disturbance), each record with its own power-law floor (model error differs
   between records).  The bin-wise minimum of rule 3 suits detection but not the shape: where
   the records' floors differ it takes each bin from whichever record is lowest there, so the
   flanks and the peak can come from different records.  The detection's estimate stays when
   the joint fit leaves the bounds of rule 5 or moves the frequency by more than
   ``SEPARATION`` half-widths.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .disturbance_spectrum import (
    LINE_HALF_WIDTH,
    LINE_SPACING,
    MIN_SEGMENTS,
    SEGMENT_SECONDS,
    on_common_grid,
    record_spectrum,
    residual_spectra,
    segment_samples,
)
from .dynamics import zoh_resonance

__all__ = [
    "DisturbanceMode",
    "disturbance_modes",
    "residual_spectra",
    "record_spectrum",
    "resonance_filter",
    "SEGMENT_SECONDS",
    "MIN_SEGMENTS",
    "BAND",
    "CANDIDATE_RATIO",
    "PEAK_RATIO",
    "MAX_DAMPING",
    "MAX_MODES",
    "SPAN",
    "LINE_SPACING",
    "SEPARATION",
    "POLE_DAMPING",
    "MAX_NFEV",
    "LINE_HALF_WIDTH",
    "PRECISION_ULPS",
    "numerical_floor",
]

#: Search band as fractions of the sampling rate.
BAND = (0.02, 0.4)
#: A local maximum of the detection spectrum at least this far above the floor is fitted.
CANDIDATE_RATIO = 4.0
#: The fitted resonance peak must stand this far above the floor.
PEAK_RATIO = 6.0
#: Largest damping ratio of a mode.
MAX_DAMPING = 0.05
#: Most modes taken.
MAX_MODES = 2
#: Most residual evaluations of one peak fit (the fits on the FORC records take 10-33; a
#: candidate on a steep model-error floor can wander for thousands).
MAX_NFEV = 200
#: A complex pole pair of the dynamics below this damping already holds a resonance (rule 6).
POLE_DAMPING = 0.3
#: Half-power half-widths around a mode or pole within which no further mode is taken.
SEPARATION = 5.0
#: The fit window around a candidate: [f / SPAN, f * SPAN].
SPAN = 1.4
#: RMS of the numerical floor in units of ``eps * output_scale``: filters and creep lags run
#: over tens of thousands of samples, whose rounding adds up far beyond one unit.
PRECISION_ULPS = 1e4


@dataclass(frozen=True)
class DisturbanceMode:
    """A lightly damped mode seen in the records' disturbance.

    Attributes
    ----------
    frequency_hz, damping : float
        Natural frequency and damping ratio of the fitted resonance.
    peak_ratio : float
        Fitted peak of the detection spectrum over its floor.
    """

    frequency_hz: float
    damping: float
    peak_ratio: float


def _detection_spectrum(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(s, measured)``: the bin-wise minimum over the records, and where every record has
    the bin; elsewhere ``s`` is its neighbours' (interpolated, for the floor only)."""
    measured = np.all(~np.isnan(P), axis=0)
    s = np.full(P.shape[1], np.nan)
    s[measured] = P[:, measured].min(axis=0)
    if measured.any() and not measured.all():
        idx = np.arange(s.size)
        s[~measured] = np.interp(idx[~measured], idx[measured], s[measured])
    return s, measured


def _floor(f: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Median of ``s`` over ``[f/2, 2f]`` at every bin (the noise floor beside a peak)."""
    out = np.empty_like(s)
    for k, fk in enumerate(f):
        m = (f >= fk / 2) & (f <= 2 * fk)
        out[k] = np.median(s[m])
    return out


def _hann_kernel(nper: int, oversample: int) -> np.ndarray:
    """``|W|^2`` of the Hann window on a grid ``oversample`` times finer than the bins, normalised."""
    w = np.hanning(nper + 1)[:-1]
    W = np.abs(np.fft.fft(w, nper * oversample)) ** 2
    half = 4 * oversample  # the main lobe and the first side lobes
    k = np.r_[W[-half:], W[: half + 1]]
    return k / k.sum()


def _expected(f: np.ndarray, fn: float, zeta: float, df: float, kernel: np.ndarray, oversample: int) -> np.ndarray:
    """``|R|^2`` convolved with the window kernel, at the bins ``f``."""
    half = (kernel.size - 1) // 2
    step = df / oversample
    fine = f[:, None] + step * np.arange(-half, half + 1)[None, :]
    r = fine / fn
    mag = 1.0 / ((1 - r**2) ** 2 + (2 * zeta * r) ** 2)
    return mag @ kernel


def numerical_floor(output_scale: float, dt: float) -> float:
    """One-sided PSD of white noise of RMS ``PRECISION_ULPS * eps * output_scale`` (rule 4)."""
    return 2.0 * dt * (PRECISION_ULPS * np.finfo(float).eps * abs(float(output_scale))) ** 2


def _fit_peak(
    f: np.ndarray, s: np.ndarray, measured: np.ndarray, fp: float, floor0: float, dt: float, least: float = 0.0
):
    """``(fn, zeta, peak over floor)`` of ``floor + K |R|^2`` fitted to ``s`` near ``fp``; the
    fitted floor counts as at least ``least`` (the numerical floor)."""
    from scipy.optimize import least_squares

    over = 8
    nper = segment_samples(dt)
    df = f[1] - f[0]
    kernel = _hann_kernel(nper, over)
    m = (f >= fp / SPAN) & (f <= fp * SPAN) & (s > 0) & measured
    fw, sw = f[m], np.log(s[m])
    zeta0 = max(2 * df / fp, 0.01)
    k0 = max(float(np.exp(sw.max())) - floor0, floor0) * (2 * zeta0) ** 2

    def model(p):
        fn, zeta = p[0] * fp, np.exp(p[1])
        return np.logaddexp(p[3] + p[4] * np.log(fw / fp), p[2] + np.log(_expected(fw, fn, zeta, df, kernel, over)))

    # the floor is a power law in f: model error beside the mode falls with frequency
    p0 = np.r_[1.0, np.log(zeta0), np.log(k0), np.log(floor0), 0.0]
    lo = np.r_[1 / SPAN, np.log(1e-4), -np.inf, -np.inf, -20.0]
    hi = np.r_[SPAN, np.log(1.0), np.inf, np.inf, 20.0]
    res = least_squares(lambda p: model(p) - sw, p0, bounds=(lo, hi), loss="soft_l1", f_scale=0.5, max_nfev=MAX_NFEV)
    fn, zeta = float(res.x[0] * fp), float(np.exp(res.x[1]))
    # the peak as the Welch estimate sees it (window-smoothed), not the resonance's own
    peak = np.exp(res.x[2]) * float(np.max(_expected(fw, fn, zeta, df, kernel, over)))
    return fn, zeta, float(1 + peak / max(np.exp(res.x[3]), least))


def disturbance_modes(
    residuals: list[np.ndarray],
    drives: list[np.ndarray],
    dt: float,
    poles: np.ndarray | None = None,
    output_scale: float | None = None,
) -> tuple[DisturbanceMode, ...]:
    """The lightly damped modes that the rule of this module finds in the records' residuals.

    Parameters
    ----------
    residuals : list of ndarray
        Per record, measured minus modelled output (any offset; the mean is removed).
    drives : list of ndarray
        Per record, the drive (its fundamental locates the harmonics, rule 3).
    dt : float
        Sampling period [s].
    poles : ndarray, optional
        Discrete poles of the dynamics already in the model (rule 6).
    output_scale : float, optional
        The records' largest absolute output, which sets the numerical floor (rule 4); by
        default the largest absolute residual (a floor that only rules out pure rounding).
    """
    own = [sp for sp in (record_spectrum(e, u, dt) for e, u in zip(residuals, drives)) if sp is not None]
    f, P = on_common_grid(own, dt)
    if P.shape[0] == 0:
        return ()
    s, measured = _detection_spectrum(P)
    if not measured.any():
        return ()
    if output_scale is None:
        output_scale = max(float(np.max(np.abs(e))) for e in residuals)
    least = numerical_floor(output_scale, dt)
    floor = np.maximum(_floor(f, s), least)
    fs = 1.0 / dt
    df = f[1] - f[0]
    inside = (f >= BAND[0] * fs) & (f <= BAND[1] * fs) & measured
    ratio = np.where(floor > 0, s / np.where(floor > 0, floor, 1.0), 0.0)
    peaks = [k for k in range(1, f.size - 1) if inside[k] and ratio[k] >= max(ratio[k - 1], ratio[k + 1])]
    peaks = sorted((k for k in peaks if ratio[k] >= CANDIDATE_RATIO), key=lambda k: -ratio[k])
    taken: list[DisturbanceMode] = []
    resonant = _resonant_poles(poles, dt)
    # before the fit the candidate's damping is unknown: the poles' own half-widths (capped)
    bands = [(fp * (1 - SEPARATION * zp), fp * (1 + SEPARATION * zp)) for fp, zp in resonant]
    for k in peaks:
        if len(taken) >= MAX_MODES:
            break
        if any(lo <= f[k] <= hi for lo, hi in bands):
            continue
        try:
            fn, zeta, peak = _fit_peak(f, s, measured, float(f[k]), float(floor[k]), dt, least)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if peak >= PEAK_RATIO and 2 * zeta * fn < df:
            if abs(fn - f[k]) <= df:
                # a line narrower than a bin, at its own measured peak: the window's leakage
                # beside it is no mode either (off its peak, the fit saw only a shoulder)
                bands.append((fn - SEPARATION * df, fn + SEPARATION * df))
            continue
        if peak < PEAK_RATIO or zeta > MAX_DAMPING:
            continue
        if any(lo <= fn <= hi for lo, hi in bands):
            continue
        if any(abs(fn - fp) <= SEPARATION * max(zeta, zp) * fp for fp, zp in resonant):
            continue
        fn, zeta = _refine_jointly(own, fn, zeta, df)
        taken.append(DisturbanceMode(fn, zeta, peak))
        bands.append((fn * (1 - SEPARATION * zeta), fn * (1 + SEPARATION * zeta)))
    return tuple(sorted(taken, key=lambda m: m.frequency_hz))


def _refine_jointly(spectra: list, fn0: float, zeta0: float, df: float) -> tuple[float, float]:
    """``(fn, zeta)`` of a found mode fitted to every record's own spectrum at once (rule 7): one
    resonance and one ring level common to all records, each record with its own power-law floor.
    The detection's estimate when the joint fit leaves the mode's bounds (damping in
    ``[df / (2 fn), MAX_DAMPING]``, frequency within ``SEPARATION`` half-widths)."""
    from scipy.optimize import least_squares

    over = 8
    parts = []
    for ff, p, nper in spectra:
        m = (ff >= fn0 / SPAN) & (ff <= fn0 * SPAN) & (p > 0)  # NaN (harmonic) bins compare False
        if m.sum() >= 5:  # a floor (2 numbers) and its share of the resonance need a few bins
            parts.append((ff[m], np.log(p[m]), ff[1] - ff[0], _hann_kernel(nper, over)))
    if not parts:
        return fn0, zeta0

    def residual(x):
        fn, zeta = x[0] * fn0, np.exp(x[1])
        out = []
        for j, (fw, lw, dfj, kernel) in enumerate(parts):
            ring = x[2] + np.log(_expected(fw, fn, zeta, dfj, kernel, over))
            out.append(np.logaddexp(x[3 + 2 * j] + x[4 + 2 * j] * np.log(fw / fn0), ring) - lw)
        return np.concatenate(out)

    floors = np.ravel([[np.median(lw), 0.0] for _, lw, _, _ in parts])
    peak = max(float(np.max(lw)) for _, lw, _, _ in parts)
    lo = np.r_[1 / SPAN, np.log(1e-4), -np.inf, np.tile([-np.inf, -20.0], len(parts))]
    hi = np.r_[SPAN, 0.0, np.inf, np.tile([np.inf, 20.0], len(parts))]
    best = None
    for z in (zeta0 / 2, zeta0, 2 * zeta0):  # the log-spectrum fit has local minima in the damping
        x0 = np.r_[1.0, np.log(z), peak + 2 * np.log(2 * z), floors]
        try:
            res = least_squares(residual, x0, bounds=(lo, hi), loss="soft_l1", f_scale=0.5, max_nfev=MAX_NFEV)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        return fn0, zeta0
    fn, zeta = float(best.x[0] * fn0), float(np.exp(best.x[1]))
    if 2 * zeta * fn < df or zeta > MAX_DAMPING or abs(fn - fn0) > SEPARATION * zeta0 * fn0:
        return fn0, zeta0
    return fn, zeta


def _resonant_poles(poles: np.ndarray | None, dt: float) -> list[tuple[float, float]]:
    """``(fn, min(zeta, MAX_DAMPING))`` of the complex pole pairs of the dynamics with damping
    below ``POLE_DAMPING`` (rule 6)."""
    out = []
    for z in np.atleast_1d(poles if poles is not None else []):
        z = complex(z)
        if z == 0 or z.imag <= 0:
            continue
        s = np.log(z) / dt
        zeta = -s.real / abs(s)
        if zeta < POLE_DAMPING:
            out.append((abs(s) / (2 * np.pi), min(zeta, MAX_DAMPING)))
    return out


def resonance_filter(modes: tuple[DisturbanceMode, ...], dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` in ``z^-1`` of the product of the modes' resonances, ZOH-sampled, unit DC gain.

    Each mode is ``wn^2 / (s^2 + 2 zeta wn s + wn^2)`` held over a sample (no zeros near the
    mode: its numerator is ``b_1 z^-1 + b_2 z^-2``).
    """
    b, a = np.ones(1), np.ones(1)
    for m in modes:
        num, den = zoh_resonance(m.frequency_hz, m.damping, dt)
        b, a = np.convolve(b, num), np.convolve(a, den)
    return b, a
