"""Rate-dependent stage study (issue 16): joint hysteresis + creep + dynamics on real and simulated stages.

Run: ``OMP_NUM_THREADS=1 python studies/hysteresis/stage_study.py [--skip-real]``; prints a
Markdown summary (the figures quoted in ``studies/hysteresis/RESULTS.md`` section 4).

1. Simulated stage: a discrete Preisach actuator (relays on a triangular threshold grid,
   asymmetric smooth weights -- not a PI model) followed by a lightly damped resonance
   (1 kHz, damping 0.05) at 10 kHz sampling.  Identified by ``StageIdentifier`` on decaying
   triangles at 20 and 100 Hz; validated on a 150 Hz decaying triangle; a 100 Hz triangle
   scan over 80 % of the range tracked with the rate-independent inverse and with the stage
   inverse (:func:`stageid.hysteresis.stage_inverse.stage_feedforward`).
2. dSPACE records: identified on the 20 Hz and 100 Hz FORC records with ``dynamics="auto",
   creep="auto"``; every validation record gets its own output offset (mean residual) and the
   best of the three starting-state kinds, the model is untouched.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE / "output"
DT = 1e-4


def _aligned(model, u, y):
    """The model's output on a record with that record's own offset and best starting state."""
    best = None
    for kind in ("zero", "ascending", "descending"):
        h = model.hysteresis.with_state(model.hysteresis.consistent_state(u[0], kind))
        yh = model.with_hysteresis(h).simulate(u, DT)[:, 0]
        yh = yh + np.mean(y - yh)
        sse = float(np.sum((y - yh) ** 2))
        best = (sse, yh) if best is None or sse < best[0] else best
    return best[1]


def _figures(name, u, y, models) -> None:
    """Loop and error-trace PNGs of one record (git-ignored ``output/``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stageid.plots.hysteresis import loop_figure, model_errors_figure

    OUT.mkdir(exist_ok=True)
    preds = {label: _aligned(m, u, y) for label, m in models.items()}
    fig = loop_figure(u, {"measured": y, **preds}, title=f"{name}: loops")
    fig.savefig(OUT / f"stage_{name}_loops.png", dpi=90)
    plt.close(fig)
    t = np.arange(u.size) * DT
    fig = model_errors_figure(t, {label: y - p for label, p in preds.items()}, title=f"{name}: error")
    fig.savefig(OUT / f"stage_{name}_errors.png", dpi=90)
    plt.close(fig)


class PreisachActuator:
    """Discrete Preisach model: relays ``(alpha >= beta)`` on an ``n x n`` grid over ``[-scale, scale]`` V.

    The grid is fine (160: 0.25 %-of-range relay steps): a coarse grid makes a staircase output
    whose steps, at scan rates, fall near the resonance and ring it.
    """

    def __init__(self, n: int = 160, scale: float = 100.0) -> None:
        g = np.linspace(-1, 1, n)
        A, B = np.meshgrid(g, g, indexing="ij")  # alpha (up switch), beta (down switch)
        keep = A >= B
        self.alpha = A[keep] * scale
        self.beta = B[keep] * scale
        # asymmetric, smooth weights: more mass near the diagonal and on the positive side
        w = np.exp(-(((A - B) / 0.6) ** 2)) * (1.0 + 0.3 * (A + B))
        self.w = w[keep] / w[keep].sum()
        self.scale = scale

    def simulate(self, u: np.ndarray) -> np.ndarray:
        # demagnetised at 0 V (the staircase on alpha = -beta), then the first sample: the
        # identified models' "zero" start, so a drive that begins elsewhere jumps there from 0 V
        state = np.where(self.alpha + self.beta <= 0.0, 1.0, -1.0)
        y = np.empty(u.size)
        for k, x in enumerate(u):
            state[x >= self.alpha] = 1.0
            state[x <= self.beta] = -1.0
            y[k] = self.w @ state
        return 10.0 * y + 0.02 * u  # um: relays plus a small reversible part


def resonance(dt: float, f_n: float = 1000.0, zeta: float = 0.05):
    from scipy.signal import cont2discrete

    from stageid.hysteresis.stage.dynamics import transfer_to_statespace

    wn = 2 * np.pi * f_n
    b, a, _ = cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), dt, "zoh")
    b = np.ravel(b)
    return b * np.sum(a) / np.sum(b), a, transfer_to_statespace(b * np.sum(a) / np.sum(b), a, dt)


def simulated_stage(seed: int = 0):
    """``(plant, rec)``: the Preisach actuator + 1 kHz resonance, and ``rec(freq, cycles, name)``,
    a noisy decaying-triangle record of it (the noise drawn in call order from ``seed``)."""
    from scipy.signal import lfilter

    from stageid.data import Experiment
    from stageid.signals import decaying_triangle

    act = PreisachActuator()
    b, a, _ = resonance(DT)
    rng = np.random.default_rng(seed)

    def plant(u):
        h = act.simulate(u)
        return h[0] + lfilter(b, a, h - h[0])

    def rec(freq, cycles, name):
        u = decaying_triangle(freq, cycles, DT, amplitude=95.0)
        y = plant(u) + 2e-3 * rng.standard_normal(u.size)
        return Experiment(u[:, None], y[:, None], DT, ("V",), ("y",), name=name)

    return plant, rec


def simulated(lines: list[str]) -> None:
    from stageid.hysteresis import compensate
    from stageid.hysteresis.stage.identification import StageIdentifier
    from stageid.hysteresis.stage.inverse import stage_feedforward
    from stageid.signals import triangle

    plant, rec = simulated_stage()
    train = [rec(20.0, 12, "20 Hz"), rec(100.0, 40, "100 Hz")]
    t0 = time.perf_counter()
    fit = StageIdentifier("modified-pi", dynamics="auto", creep=None).fit(train)
    if "--order-2" in sys.argv:
        fit = StageIdentifier("modified-pi", dynamics=2, creep=None).fit(train)
    t_fit = time.perf_counter() - t0
    ri = StageIdentifier("modified-pi", dynamics=None, creep=None).fit(train)
    lines.append("## Simulated Preisach actuator + 1 kHz resonance (damping 0.05), 10 kHz\n")
    lines.append(f"Identification (dynamics auto, {t_fit:.1f} s):\n\n```\n{fit.summary()}\n```\n")
    val = rec(150.0, 40, "150 Hz")
    lines.append("| record | rate-independent modified PI max / RMS % | stage model max / RMS % |")
    lines.append("|---|---|---|")
    for e in [*train, val]:
        u, y = e.u[:, 0], e.y[:, 0]
        cells = []
        for m in (ri.model, fit.model):
            yh = m.with_hysteresis(m.hysteresis.with_state(m.hysteresis.consistent_state(u[0], "zero"))).simulate(u, DT)
            err = y - yh[:, 0]
            err = err - err.mean()
            cells.append(
                f"{100 * np.abs(err).max() / np.ptp(y):.2f} / {100 * np.sqrt(np.mean(err**2)) / np.ptp(y):.2f}"
            )
        lines.append(f"| {e.name} | {cells[0]} | {cells[1]} |")
    # tracking: 100 Hz triangle over 80 % of the output range
    y_lo, y_hi = float(plant(np.r_[-95.0, -95.0])[-1]), float(plant(np.r_[95.0, 95.0])[-1])
    mid, half = 0.5 * (y_lo + y_hi), 0.4 * (y_hi - y_lo)
    n_cyc = 5
    ref = mid + half * triangle(100.0, n_cyc, DT)
    ref = np.r_[np.full(200, ref[0]), ref]
    lines.append("\nTracking a 100 Hz triangle over 80 % of the range (error after the first cycle, % FSR):\n")
    lines.append("| drive | max | RMS |")
    lines.append("|---|---|---|")
    drives = {
        "rate-independent inverse (hysteresis only)": compensate(fit.model.hysteresis, ref, limits=(-95.0, 95.0)),
        "stage inverse (dynamics + hysteresis)": stage_feedforward(fit.model, ref, DT, limits=(-95.0, 95.0)),
    }
    first = 200 + int(round(1 / 100.0 / DT))
    for name, u in drives.items():
        y = plant(u[:, 0])
        e = (y - ref)[first:]
        fsr = 2 * half
        lines.append(f"| {name} | {100 * np.abs(e).max() / fsr:.2f} | {100 * np.sqrt(np.mean(e**2)) / fsr:.2f} |")
    lines.append("")


def real(lines: list[str]) -> None:
    sys.path.insert(0, str(HERE))
    from run_study import _trim_dspace

    from stageid.data.datasets import load_dspace_piezo, shared_data_dir
    from stageid.hysteresis.stage.identification import StageIdentifier

    root = shared_data_dir()
    folder = None if root is None else root / "piezo_dspace_preisach"
    if folder is None or not folder.is_dir():
        lines.append("## dSPACE records: data not found, skipped\n")
        return
    names = ["20_hz_no_lp", "40_hz_no_lp", "100_hz_no_lp", "tri50_1", "tri100_1", "sine50_1", "sine100_1"]
    names += ["prbn_1", "bigsine_1"]
    recs = {n: _trim_dspace(load_dspace_piezo(folder / f"{n}.mat")) for n in names}
    train = [recs["20_hz_no_lp"], recs["100_hz_no_lp"]]
    configs = {
        "rate-independent modified PI": dict(dynamics=None, creep=None),
        "dynamics auto, creep auto": dict(dynamics="auto", creep="auto"),
        "dynamics 2, creep 0.05 s": dict(dynamics=2, creep=(0.05,)),
    }
    fits = {}
    for label, kw in configs.items():
        t0 = time.perf_counter()
        fits[label] = StageIdentifier("modified-pi", sample_time=DT, **kw).fit(train)
        lines.append(f"`{label}`: fit {time.perf_counter() - t0:.1f} s\n\n```\n{fits[label].summary()}\n```\n")
    lines.append("## dSPACE records, identified on 20 Hz + 100 Hz FORC (max / RMS % of range)\n")
    lines.append("| record | " + " | ".join(configs) + " |")
    lines.append("|---|" + "---|" * len(configs))
    for n in names:
        u, y = recs[n]
        cells = []
        for label in configs:
            m = fits[label].model
            best = None
            for kind in ("zero", "ascending", "descending"):
                h = m.hysteresis.with_state(m.hysteresis.consistent_state(u[0], kind))
                e = y - m.with_hysteresis(h).simulate(u, DT)[:, 0]
                e = e - e.mean()  # the record's own sensor zero
                cand = (float(np.sqrt(np.mean(e**2))), float(np.abs(e).max()))
                best = cand if best is None or cand[0] < best[0] else best
            cells.append(f"{100 * best[1] / np.ptp(y):.2f} / {100 * best[0] / np.ptp(y):.2f}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
        _figures(n, u, y, {label: fits[label].model for label in configs})
    lines.append(f"\nLoops and error traces per record: `{OUT.relative_to(HERE)}/stage_*.png`.\n")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    lines: list[str] = ["# Stage study (issue 16)\n"]
    simulated(lines)
    if "--skip-real" not in argv:
        real(lines)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
