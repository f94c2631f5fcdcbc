"""Preisach hysteresis inside the stage model (issue 16): simulated scan and dSPACE records.

Run: ``OMP_NUM_THREADS=1 python studies/hysteresis/preisach_stage_study.py [--sim] [--real]
[--config NAME ...]``; prints Markdown (the figures of ``studies/hysteresis/RESULTS.md``
section 4d).

1. Simulated stage (the one of ``stage_study.py``: a fine relay Preisach actuator followed by a
   1 kHz resonance, damping 0.05, 10 kHz): ``StageIdentifier("preisach", dynamics="auto")`` on
   the 20 and 100 Hz decaying triangles; validated on the 150 Hz decaying triangle; a 100 Hz
   triangle over 80 % of the range tracked by the stage inverse (0.5 s, error after the first
   cycle, % FSR).
2. dSPACE records: identified on the 20 Hz + 100 Hz FORC records; every record validated
   twice with the model fixed (``stageid.hysteresis.stage_validation.validate_record``):
   ``kinds`` (own offset = sensor zero, best of the three standard starting memories) and
   ``estimate`` (the record's initial condition estimated: offset, one earlier minor loop,
   the dynamics' and creep states).  Where the error sits (first 0.2 s against the rest), and
   the ~740 Hz resonance of the tracking records that the FORC drives do not excite: the
   auto model takes it from the FORC records' disturbance (``disturbance_modes``, section 4f
   of RESULTS.md); the same recipe without that step, the mode in the FORC records' output
   noise, and the session-9 check (the model without it plus a resonance, weights refitted).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DT = 1e-4
NAMES = ["20_hz_no_lp", "40_hz_no_lp", "100_hz_no_lp", "tri50_1", "tri100_1", "sine50_1", "sine100_1"]
NAMES += ["prbn_1", "bigsine_1"]
TRACKING = NAMES[3:]
NO_MODES = "preisach, dynamics auto, creep auto, no disturbance modes"
CONFIGS = {
    "preisach, rate independent": dict(dynamics=None, creep=None),
    "preisach, dynamics auto, creep auto": dict(dynamics="auto", creep="auto"),
    NO_MODES: dict(dynamics="auto", creep="auto", disturbance_modes=None),
    "preisach, dynamics 1, creep 0.01/0.1/1 s": dict(dynamics=1, creep=(0.01, 0.1, 1.0)),
}


def aligned_error(model, u, y, initial: str = "kinds") -> np.ndarray:
    """Error of the stage model on a record with its initial condition fitted on it
    (:func:`~stageid.hysteresis.stage_validation.validate_record`: ``"kinds"`` own offset and
    the best of the three standard memories; ``"estimate"`` also an earlier minor loop and the
    linear states)."""
    from stageid.hysteresis.stage.validation import validate_record

    return y - validate_record(model, u, y, DT, initial).simulated


def figures(name: str, u: np.ndarray, y: np.ndarray, models: dict) -> None:
    """Loop and error-trace PNGs of one record in ``output/`` (git-ignored)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stageid.plots.hysteresis import loop_figure, model_errors_figure

    out = HERE / "output"
    out.mkdir(exist_ok=True)
    errors = {label: aligned_error(m, u, y) for label, m in models.items()}
    fig = loop_figure(u, {"measured": y, **{k: y - e for k, e in errors.items()}}, title=f"{name}: loops")
    fig.savefig(out / f"preisach_stage_{name}_loops.png", dpi=90)
    plt.close(fig)
    fig = model_errors_figure(np.arange(u.size) * DT, errors, title=f"{name}: error (own offset)")
    fig.savefig(out / f"preisach_stage_{name}_errors.png", dpi=90)
    plt.close(fig)


def simulated(lines: list[str]) -> None:
    from stage_study import simulated_stage

    from stageid.hysteresis.stage.identification import StageIdentifier
    from stageid.hysteresis.stage.inverse import stage_feedforward
    from stageid.signals import triangle

    plant, rec = simulated_stage()  # the same plant and records as stage_study.py
    train = [rec(20.0, 12, "20 Hz"), rec(100.0, 40, "100 Hz")]
    val = rec(150.0, 40, "150 Hz")
    y_lo, y_hi = float(plant(np.r_[-95.0, -95.0])[-1]), float(plant(np.r_[95.0, 95.0])[-1])
    mid, half = 0.5 * (y_lo + y_hi), 0.4 * (y_hi - y_lo)
    ref = mid + half * triangle(100.0, 0.5, DT)
    ref = np.r_[np.full(200, ref[0]), ref]
    first = 200 + int(round(1 / 100.0 / DT))
    lines.append("## Simulated Preisach actuator + 1 kHz resonance: Preisach stage model\n")
    lines.append(
        "| levels | dynamics | fit CPU s | 20 Hz | 100 Hz | 150 Hz (validation) | 100 Hz scan max / RMS % FSR |"
    )
    lines.append("|---|---|---|---|---|---|---|")
    for levels in (20, 30):
        for dyn in ("auto", 2):
            t0 = time.process_time()
            fit = StageIdentifier("preisach", n_levels=levels, dynamics=dyn, creep=None).fit(train)
            cpu = time.process_time() - t0
            cells = []
            for e in [*train, val]:
                u, y = e.u[:, 0], e.y[:, 0]
                m = fit.model
                h = m.hysteresis.with_state(m.hysteresis.consistent_state(u[0], "zero"))
                err = y - m.with_hysteresis(h).simulate(u, DT)[:, 0]
                err = err - err.mean()
                cells.append(
                    f"{100 * np.abs(err).max() / np.ptp(y):.2f} / {100 * np.sqrt(np.mean(err**2)) / np.ptp(y):.2f}"
                )
            drive = stage_feedforward(fit.model, ref, DT, limits=(-95.0, 95.0))[:, 0]
            e = (plant(drive) - ref)[first:]
            scan = f"{100 * np.abs(e).max() / (2 * half):.2f} / {100 * np.sqrt(np.mean(e**2)) / (2 * half):.2f}"
            label = f"{dyn} (order {fit.dynamics_order})"
            lines.append(f"| {levels} | {label} | {cpu:.1f} | " + " | ".join(cells) + f" | {scan} |")
            print(fit.summary(), file=sys.stderr)
    lines.append("")


def percent(e: np.ndarray, y: np.ndarray) -> str:
    """``max / RMS`` of an error in % of the record's output range."""
    return f"{100 * np.abs(e).max() / np.ptp(y):.2f} / {100 * np.sqrt(np.mean(e**2)) / np.ptp(y):.2f}"


def rms(e: np.ndarray, y: np.ndarray) -> float:
    return float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y))


def real(lines: list[str], configs: list[str]) -> None:
    from run_study import _trim_dspace

    from stageid.data.datasets import load_dspace_piezo, shared_data_dir
    from stageid.hysteresis.stage.identification import StageIdentifier
    from stageid.hysteresis.stage.validation import validate_record

    root = shared_data_dir()
    folder = None if root is None else root / "piezo_dspace_preisach"
    if folder is None or not folder.is_dir():
        lines.append("## dSPACE records: data not found, skipped\n")
        return
    recs = {n: _trim_dspace(load_dspace_piezo(folder / f"{n}.mat")) for n in NAMES}
    train = [recs["20_hz_no_lp"], recs["100_hz_no_lp"]]
    fits = {}
    for label in configs:
        t0 = time.process_time()
        fits[label] = StageIdentifier("preisach", sample_time=DT, **CONFIGS[label]).fit(train)
        lines.append(f"`{label}`: fit {time.process_time() - t0:.1f} s CPU\n\n```\n{fits[label].summary()}\n```\n")
    lines.append("## dSPACE records, Preisach stage identified on 20 Hz + 100 Hz FORC\n")
    lines.append("max / RMS % of range.  `kinds`: own offset and the best of the three standard starting")
    lines.append("memories (as the identification; the figure of the earlier sessions).  `estimate`: the")
    lines.append("record's initial condition estimated with the model fixed (`validate_record`,")
    lines.append("`stageid validate --initial estimate`): offset, one earlier minor loop (2 levels), the")
    lines.append("dynamics' and creep lags' states.\n")
    lines.append("| record | " + " | ".join(f"{c}: kinds | {c}: estimate" for c in configs) + " |")
    lines.append("|---|" + "---|---|" * len(configs))
    vals = {}
    for n in NAMES:
        u, y = recs[n]
        cells = []
        for label in configs:
            for initial in ("kinds", "estimate"):
                r = validate_record(fits[label].model, u, y, DT, initial)
                vals[label, initial, n] = r
                cells.append(f"{r.max_error_percent:.2f} / {r.rms_error_percent:.2f}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
        figures(n, u, y, {label: fits[label].model for label in configs})
    lines.append("\nLoops and error traces per record: `output/preisach_stage_*.png`.\n")
    main_label = configs[1] if len(configs) > 1 else configs[0]
    lines.append(f"### Where the tracking records' error sits (`{main_label}`), RMS % of range\n")
    lines.append(
        "| record | kinds: all | first 0.2 s | rest | estimate: all | first 0.2 s | rest | estimated memory "
        "| n_free | memory only (3 numbers) |"
    )
    lines.append("|---|---|---|---|---|---|---|---|---|---|")
    k = int(0.2 / DT)
    for n in TRACKING:
        u, y = recs[n]
        a, b = vals[main_label, "kinds", n], vals[main_label, "estimate", n]
        ea, eb = y - a.simulated, y - b.simulated
        lines.append(
            f"| {n} | {rms(ea, y):.2f} | {rms(ea[:k], y):.2f} | {rms(ea[k:], y):.2f} | {rms(eb, y):.2f} | "
            f"{rms(eb[:k], y):.2f} | {rms(eb[k:], y):.2f} | {b.memory} | {b.n_free} | "
            f"{validate_record(fits[main_label].model, u, y, DT, 'memory').rms_error_percent:.2f} |"
        )
    lines.append("")
    if NO_MODES in fits:
        disturbance(lines, recs, train, fits[NO_MODES])
        resonance(lines, recs, train, fits[NO_MODES])


def disturbance(lines: list[str], recs: dict, train: list, fit) -> None:
    """The FORC records' output noise near the mode: band RMS of ``y - savgol(y, 51, 3)`` and of
    the drive, and what the rule of :mod:`stageid.hysteresis.disturbance_modes` finds in the
    residual of the model without modes, per FORC record and for the identification pair."""
    from scipy.signal import savgol_filter, welch

    from stageid.hysteresis.stage.disturbance_modes import disturbance_modes
    from stageid.hysteresis.stage.validation import validate_record

    lines.append("### The mode in the FORC records' disturbance\n")
    lines.append("Band RMS of the fast part `y - savgol(y, 51, 3)` [um] and of the drive's [V] (Welch, 4096):\n")
    lines.append("| record | 300-600 Hz | 600-900 Hz | 900-1200 Hz | largest peak 200-2000 Hz | drive 600-900 Hz |")
    lines.append("|---|---|---|---|---|---|")
    for n in NAMES[:3]:
        u, y = recs[n]
        f, p = welch(y - savgol_filter(y, 51, 3), fs=1 / DT, nperseg=4096)
        _, pu = welch(u - savgol_filter(u, 51, 3), fs=1 / DT, nperseg=4096)
        k = np.flatnonzero((f >= 200) & (f <= 2000))
        peak = f[k[np.argmax(p[k])]]
        lines.append(
            f"| {n} | {band_rms(f, p, 300, 600):.5f} | {band_rms(f, p, 600, 900):.5f} | "
            f"{band_rms(f, p, 900, 1200):.5f} | {peak:.1f} Hz | {band_rms(f, pu, 600, 900):.5f} |"
        )
    m = fit.model
    u0 = [u for u, _ in train]
    # the identification records' residual: own offset and starting memory, as in the fit
    res = [y - validate_record(m, u, y, DT, "kinds").simulated for u, y in train]
    lines.append("\nThe rule on the residual of the model without modes (`" + NO_MODES + "`):\n")
    for label, r, u in (("20 Hz alone", res[:1], u0[:1]), ("100 Hz alone", res[1:], u0[1:]), ("both", res, u0)):
        found = disturbance_modes(r, u, DT, m.dynamics.poles() if m.dynamics is not None else None)
        text = ", ".join(f"{d.frequency_hz:.1f} Hz, damping {d.damping:.4f}, peak {d.peak_ratio:.1f}" for d in found)
        lines.append(f"- {label}: {text or 'none'}")
    lines.append("")


def band_rms(f: np.ndarray, psd: np.ndarray, lo: float, hi: float) -> float:
    """RMS of a one-sided PSD over ``[lo, hi)``."""
    m = (f >= lo) & (f < hi)
    return float(np.sqrt(np.sum(psd[m]) * (f[1] - f[0])))


def resonance(lines: list[str], recs: dict, train: list, fit) -> None:
    """The ~740 Hz resonance of the tracking records: their small-signal response (Welch H1),
    the drive power near it in every record, and the model with it added, weights refitted on
    the FORC records only."""
    from scipy.signal import csd, welch

    from stageid.hysteresis.stage.dynamics import zoh_resonance
    from stageid.hysteresis.stage.preisach import PreisachColumns, best_start_kinds
    from stageid.hysteresis.stage.problem import StageProblem
    from stageid.hysteresis.stage.validation import validate_record

    lines.append("### The resonance near 740 Hz\n")
    freqs = (5, 100, 300, 500, 650, 700, 740, 780, 900, 1500)
    lines.append("Small-signal gain |H1| [um/V] (Welch, 2000-sample segments) and drive RMS in 600-900 Hz:\n")
    lines.append("| record | " + " | ".join(f"{f} Hz" for f in freqs) + " | drive RMS 600-900 Hz [V] |")
    lines.append("|---|" + "---|" * (len(freqs) + 1))
    for n in NAMES:
        u, y = recs[n]
        f, Puu = welch(u - u.mean(), fs=1 / DT, nperseg=2000)
        _, Puy = csd(u - u.mean(), y - y.mean(), fs=1 / DT, nperseg=2000)
        band = (f >= 600) & (f < 900)
        drive = float(np.sqrt(np.sum(Puu[band]) * (f[1] - f[0])))
        cells = [f"{abs(Puy[i] / Puu[i]):.3f}" for i in (np.argmin(abs(f - x)) for x in freqs)]
        lines.append(f"| {n} | " + " | ".join(cells) + f" | {drive:.4f} |")
    model = fit.model
    h = model.hysteresis
    taus = tuple(fit.creep_time_constants)
    kinds = best_start_kinds(h, train, "auto")
    problem = StageProblem(PreisachColumns(h, train, kinds, 1e-4), DT)
    cols = problem.columns(taus)
    masks = [np.ones(u.size, bool) for u, _ in train]
    b0, a0 = model.transfer()
    lines.append("\nThe identified `G` in series with a resonance (ZOH of `wn^2 / (s^2 + 2 zeta wn s + wn^2)`),")
    lines.append("cell and creep weights refitted on the 20 + 100 Hz FORC records; RMS % of range, `estimate`:\n")
    lines.append("| resonance | " + " | ".join(NAMES) + " |")
    lines.append("|---|" + "---|" * len(NAMES))
    for fn, zeta in ((None, 0.0), (740.0, 0.02), (740.0, 0.03), (1000.0, 0.02)):
        b, a = b0, a0
        if fn is not None:
            bd, ad = zoh_resonance(fn, zeta, DT)
            b, a = np.convolve(b0, bd), np.convolve(a0, ad)
            b = np.r_[b, np.zeros(max(0, a.size - b.size))]
            a = np.r_[a, np.zeros(max(0, b.size - a.size))]
        w, offsets = problem.solve_weights(problem.filtered((b, a), cols, masks), masks, len(taus))
        nc = len(taus)
        m = problem.build(
            w[: w.size - nc], w[w.size - nc :], offsets[0], taus, (b, a) if a.size > 1 else None, "V", "y"
        )
        cells = [f"{validate_record(m, *recs[n], DT).rms_error_percent:.2f}" for n in NAMES]
        name = "none (as identified, weights refitted)" if fn is None else f"{fn:g} Hz, zeta {zeta:g}"
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines.append("")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    sys.path.insert(0, str(HERE))
    lines: list[str] = ["# Preisach stage study (issue 16)\n"]
    configs = [argv[i + 1] for i, a in enumerate(argv) if a == "--config"] or list(CONFIGS)
    if "--real" not in argv or "--sim" in argv:
        simulated(lines)
    if "--sim" not in argv or "--real" in argv:
        real(lines, configs)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
