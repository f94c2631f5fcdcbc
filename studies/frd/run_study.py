"""FRF route study: reference stage through `frf` + `identify frd`, and the measured AFM stage.

1. P-558 (stageid.plants, 3x3, 15 states, dt 2 ms): the three `random-*` experiments (one per
   excited input) -> Welch H1 with std and coherence -> FRDIdentification -> error against the
   true model over the excited band; beside it the time-domain route (HankelMAP) on the same
   records.
2. Measured AFM piezo stage `G_uz2stage` (../shared/data/afm_piezo_stage_frf, 302 lines,
   1 Hz-12 kHz, Ts = 40 us): max error over the band against order, raw McKelvey realisation
   against the refined fit, 1 Hz-2 kHz and wider bands, with and without an input delay.

    .venv/bin/python studies/frd/run_study.py [--out studies/frd]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import scipy.io

from stageid.data import datasets
from stageid.frf import FRDIdentification, FrequencyResponse, lpm_frf, welch_frf
from stageid.plants.piezo_stage import EXPERIMENTS
from stageid.plants.piezo_stage import model as p558_model


def p558_section(lines: list[str]) -> None:
    truth = p558_model()
    exps = [EXPERIMENTS[name](seed=0) for name in ("random-z", "random-rx", "random-ry")]
    frd = welch_frf(exps)
    band = frd.band(None, 100.0)  # the random experiments excite up to about 100 Hz
    G = truth.frequency_response(band.freqs)
    peak = np.max(np.abs(G), axis=(0, 1))
    welch_err = np.max(np.abs(band.response - G), axis=(0, 1)) / peak
    lines += ["## P-558 (3x3, 15 states): `frf` + `identify frd` against the true model, 1-100 Hz", ""]
    lines += ["| route | order | max error per input column (of its peak) | time [s] |", "|---|---|---|---|"]
    lines.append(f"| Welch H1 itself (the data) | - | {_fmt(welch_err)} | - |")
    for order in (6, 10, 15, "auto"):
        t = time.perf_counter()
        res = FRDIdentification(order=order, sample_time=truth.dt, band=(None, 100.0)).fit(frd)
        err = np.max(np.abs(res.model.frequency_response(band.freqs) - G), axis=(0, 1)) / peak
        lines.append(
            f"| Welch -> identify frd, order {order} | {res.order} | {_fmt(err)} | {time.perf_counter() - t:.1f} |"
        )
    t = time.perf_counter()
    res = FRDIdentification(order=15, sample_time=truth.dt).fit(frd)  # whole band: the std weights mute 100-250 Hz
    err = np.max(np.abs(res.model.frequency_response(band.freqs) - G), axis=(0, 1)) / peak
    lines.append(
        f"| Welch (whole band, std weights) -> identify frd, order 15 | 15 | {_fmt(err)} | {time.perf_counter() - t:.1f} |"
    )
    lpm = lpm_frf(exps).band(1.0, 100.0)  # lines below 1 Hz are not excited (dropped) or barely
    G_lpm = truth.frequency_response(lpm.freqs)
    lpm_err = np.max(np.abs(lpm.response - G_lpm), axis=(0, 1)) / np.max(np.abs(G_lpm), axis=(0, 1))
    lines.append(f"| LPM itself (the data, 1-100 Hz) | - | {_fmt(lpm_err)} | - |")
    for order in (10, 15, "auto"):
        t = time.perf_counter()
        res = FRDIdentification(order=order, sample_time=truth.dt).fit(lpm)
        err = np.max(np.abs(res.model.frequency_response(band.freqs) - G), axis=(0, 1)) / peak
        lines.append(
            f"| LPM -> identify frd, order {order} | {res.order} | {_fmt(err)} | {time.perf_counter() - t:.1f} |"
        )
    from stageid.subspace import HankelMAP

    t = time.perf_counter()
    hm = HankelMAP(horizon=20, order=15).fit(exps)
    err = np.max(np.abs(hm.model.frequency_response(band.freqs) - G), axis=(0, 1)) / peak
    lines.append(f"| time domain: HankelMAP(horizon=20, order=15) | 15 | {_fmt(err)} | {time.perf_counter() - t:.1f} |")
    lines.append("")


def afm_frd() -> FrequencyResponse:
    path = datasets.SHARED_DATA / "afm_piezo_stage_frf" / "FRF_data_current_stage2.mat"
    frf = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)["modelFit"].frf
    return FrequencyResponse(np.asarray(frf.freqs_Hz), np.asarray(frf.G_uz2stage), inputs=("uz",), outputs=("stage",))


def afm_section(lines: list[str], out: Path) -> None:
    frd = afm_frd()
    lines += ["## Measured AFM stage `G_uz2stage`: max error (of the peak) against order, dt = 40 us", ""]
    bands = [(1.0, 2000.0), (1.0, 5000.0), (1.0, 12193.7)]
    orders = [4, 8, 12, 16, 20, 24]
    header = "| band | delay | fit | " + " | ".join(f"n={n}" for n in orders) + " |"
    lines += [header, "|" + "---|" * (3 + len(orders))]
    curves = {}
    for lo, hi in bands:
        for delay in (0, "auto"):
            for it, label in ((0, "raw McKelvey"), (100, "refined")):
                row, found = [], set()
                for n in orders:
                    try:
                        res = FRDIdentification(order=n, sample_time=4e-5, band=(lo, hi), delay=delay, max_iter=it).fit(
                            frd
                        )
                        row.append(f"{100 * res.max_error:.2f} %")
                        found.add(res.delay)
                        curves.setdefault((lo, hi, str(delay), label), []).append((n, res.max_error))
                    except Exception as exc:  # noqa: BLE001 - a study records what failed
                        row.append(f"failed ({type(exc).__name__})")
                d = str(delay) if delay == 0 else f"auto ({','.join(map(str, sorted(found)))})"
                lines.append(f"| {lo:g}-{hi:g} Hz | {d} | {label} | " + " | ".join(row) + " |")
    lines.append("")
    res = FRDIdentification(order=16, sample_time=4e-5, band=(1.0, 2000.0)).fit(frd)
    fig = frd.band(1.0, 2000.0).plot(model=res.model)
    fig.savefig(out / "afm_order16_bode.png", dpi=110)
    _error_figure(curves, out / "afm_error_vs_order.png")
    lines += [
        f"Order 16, 1 Hz-2 kHz, delay 0: stable = {res.model.is_stable()}, max error {100 * res.max_error:.2f} % "
        "of the peak (figures: `afm_order16_bode.png`, `afm_error_vs_order.png`).",
        "",
    ]


def _error_figure(curves, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    for (lo, hi, delay, label), pts in curves.items():
        n, e = zip(*pts)
        ax.semilogy(
            n,
            100 * np.array(e),
            "o-" if label == "refined" else "x--",
            label=f"{lo:g}-{hi:g} Hz, delay {delay}, {label}",
        )
    ax.set_xlabel("order")
    ax.set_ylabel("max error [% of peak]")
    ax.legend(fontsize=6)
    fig.savefig(path, dpi=110)


def _fmt(err) -> str:
    return ", ".join(f"{100 * e:.2f} %" for e in err)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(Path(__file__).parent))
    args = ap.parse_args()
    out = Path(args.out)
    lines = ["# FRF route: measured frequency responses and `identify frd`", ""]
    p558_section(lines)
    if datasets.SHARED_DATA is not None:
        afm_section(lines, out)
    (out / "RESULTS-generated.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
