"""Preisach hysteresis inside the stage model (issue 16): simulated scan and dSPACE records.

Run: ``OMP_NUM_THREADS=1 python studies/hysteresis/preisach_stage_study.py [--sim] [--real]
[--config NAME ...]``; prints Markdown (the figures of ``studies/hysteresis/RESULTS.md``
section 4d).

1. Simulated stage (the one of ``stage_study.py``: a fine relay Preisach actuator followed by a
   1 kHz resonance, damping 0.05, 10 kHz): ``StageIdentifier("preisach", dynamics="auto")`` on
   the 20 and 100 Hz decaying triangles; validated on the 150 Hz decaying triangle; a 100 Hz
   triangle over 80 % of the range tracked by the stage inverse (0.5 s, error after the first
   cycle, % FSR).
2. dSPACE records: identified on the 20 Hz + 100 Hz FORC records; every validation record
   gets its own output offset (mean residual = sensor zero) and the best of the three
   starting-state kinds, nothing else is fitted on it.  Diagnostics of the tracking records'
   error (the model untouched): an offset + drift line per record; the RMS after the first
   0.3 s; the starting memory chosen from a family of one earlier minor loop (the records
   start after an unknown history).
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
CONFIGS = {
    "preisach, rate independent": dict(dynamics=None, creep=None),
    "preisach, dynamics auto, creep auto": dict(dynamics="auto", creep="auto"),
    "preisach, dynamics 1, creep 0.01/0.1/1 s": dict(dynamics=1, creep=(0.01, 0.1, 1.0)),
}


def aligned_error(model, u, y, detrend: bool = False) -> np.ndarray:
    """Error of the stage model on a record with its own offset (and drift line) and best start."""
    best = None
    t = np.arange(u.size) * DT
    for kind in ("zero", "ascending", "descending"):
        h = model.hysteresis.with_state(model.hysteresis.consistent_state(u[0], kind))
        e = y - model.with_hysteresis(h).simulate(u, DT)[:, 0]
        if detrend:
            e = e - np.polyval(np.polyfit(t, e, 1), t)
        else:
            e = e - e.mean()
        sse = float(e @ e)
        if best is None or sse < best[0]:
            best = (sse, e)
    return best[1]


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


def one_loop_memory_error(model, u, y) -> tuple[np.ndarray, str]:
    """Error with the starting memory chosen from the three kinds and from "rose to ``M``, fell to
    ``m``, rose to ``u[0]``" (one earlier minor loop, ``M`` and ``m`` on a 41-node grid), own offset."""
    h = model.hysteresis
    lo, hi = h.input_range
    u0 = min(max(float(u[0]), lo), hi)
    nodes = np.linspace(lo, hi, 41)
    memories = {kind: h.consistent_state(u0, kind) for kind in ("zero", "ascending", "descending")}
    memories |= {
        str([round(float(M), 1), round(float(m), 1), round(u0, 1)]): [M, m, u0]
        for M in nodes[nodes >= u0]
        for m in nodes[nodes <= u0]
    }
    best = None
    for label, mem in memories.items():
        e = y - model.with_hysteresis(h.with_state(mem)).simulate(u, DT)[:, 0]
        e = e - e.mean()
        sse = float(e @ e)
        if best is None or sse < best[0]:
            best = (sse, e, label)
    return best[1], best[2]


def simulated(lines: list[str]) -> None:
    from stage_study import simulated_stage

    from stageid.hysteresis.stage_identification import StageIdentifier
    from stageid.hysteresis.stage_inverse import stage_feedforward
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


def real(lines: list[str], configs: list[str]) -> None:
    from run_study import _trim_dspace

    from stageid.data.datasets import load_dspace_piezo, shared_data_dir
    from stageid.hysteresis.stage_identification import StageIdentifier

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
    lines.append("max / RMS % of range; own offset and best start per record.  Last columns, RMS % for")
    lines.append("the last model: an offset + drift line removed per record; only after the first 0.3 s;")
    lines.append("the starting memory chosen from one earlier minor loop (and the memory).\n")
    extra = ["offset+drift", "after 0.3 s", "one-loop start memory"]
    lines.append("| record | " + " | ".join(configs + extra) + " |")
    lines.append("|---|" + "---|" * (len(configs) + len(extra)))
    for n in NAMES:
        u, y = recs[n]
        cells = []
        for label in configs:
            e = aligned_error(fits[label].model, u, y)
            cells.append(f"{100 * np.abs(e).max() / np.ptp(y):.2f} / {100 * np.sqrt(np.mean(e**2)) / np.ptp(y):.2f}")
        m = fits[configs[-1]].model
        e = aligned_error(m, u, y, detrend=True)
        cells.append(f"{100 * np.sqrt(np.mean(e**2)) / np.ptp(y):.2f}")
        e = aligned_error(m, u, y)[int(0.3 / DT) :]
        cells.append(f"{100 * np.sqrt(np.mean((e - e.mean()) ** 2)) / np.ptp(y):.2f}")
        e, mem = one_loop_memory_error(m, u, y)
        cells.append(f"{100 * np.sqrt(np.mean(e**2)) / np.ptp(y):.2f} {mem}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
        figures(n, u, y, {label: fits[label].model for label in configs})
    lines.append("\nLoops and error traces per record: `output/preisach_stage_*.png`.\n")


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
