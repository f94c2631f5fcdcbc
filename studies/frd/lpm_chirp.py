"""Why the LPM fails at the band edges of the P-558 linear chirps, and what the std says there.

The three `chirp-*` experiments (one per input, linear 1-100 Hz sweep over the whole 10 s
record, dt 2 ms, 0.1 Hz lines) through `lpm_frf` (default window and degree 2, and wider
windows) and `welch_frf`; error against the true model per frequency, the LPM's +-2 std band,
and the line-to-line phase rotation of the input spectrum that lets the LPM tell the input's
contribution from the transient.  Writes `lpm_chirp.png` and prints a markdown table.

    .venv/bin/python studies/frd/lpm_chirp.py [--out studies/frd]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from stageid.frf import lpm_frf, welch_frf  # noqa: E402
from stageid.plants.piezo_stage import EXPERIMENTS, model  # noqa: E402

FREQS = (1.1, 2.0, 3.0, 5.0, 7.0, 10.0, 20.0, 50.0, 90.0, 99.5)


def column_error(frd, truth) -> np.ndarray:
    """Max error over the outputs, of the column's peak, per frequency and input."""
    G = truth.frequency_response(frd.freqs)
    return np.max(np.abs(frd.response - G), axis=1) / np.max(np.abs(G), axis=(0, 1))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(Path(__file__).parent))
    out = Path(ap.parse_args().out)
    truth = model()
    exps = [EXPERIMENTS[n](seed=0) for n in ("chirp-z", "chirp-rx", "chirp-ry")]
    runs = {"Welch (segment 512)": welch_frf(exps)}
    for hw in (4, None, 20):
        label = "LPM, default window (n = 9)" if hw is None else f"LPM, n = {hw}"
        runs[label] = lpm_frf(exps, half_width=hw)
    print("| estimate | " + " | ".join(f"{f:g} Hz" for f in FREQS) + " | RMS err/std |")
    print("|---|" + "---|" * (len(FREQS) + 1))
    for label, frd in runs.items():
        err = column_error(frd, truth).max(axis=1)
        cells = [f"{100 * err[np.argmin(np.abs(frd.freqs - f))]:.3g} %" for f in FREQS]
        G = truth.frequency_response(frd.freqs)
        band = (frd.freqs >= 1.0) & (frd.freqs <= 100.0)
        z = (np.abs(frd.response - G) / frd.std)[band]
        print(f"| {label} | " + " | ".join(cells) + f" | {np.sqrt(np.mean(z**2)):.2f} |")

    lpm = runs["LPM, default window (n = 9)"]
    welch = runs["Welch (segment 512)"]
    fig, ax = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    G = truth.frequency_response(lpm.freqs)[:, 0, 0]
    ax[0].loglog(lpm.freqs, np.abs(G), "k", lw=2, label="true Z/Z")
    ax[0].loglog(lpm.freqs, np.abs(lpm.response[:, 0, 0]), "C1", lw=0.8, label="LPM (default)")
    ax[0].fill_between(lpm.freqs, np.maximum(np.abs(G) - 2 * lpm.std[:, 0, 0], 1e-3), np.abs(G) + 2 * lpm.std[:, 0, 0],
                       color="C1", alpha=0.25, label="true +- 2 std (LPM)")  # fmt: skip
    ax[0].loglog(welch.freqs, np.abs(welch.response[:, 0, 0]), "C0o", ms=3, label="Welch")
    ax[0].set_ylim(1e-2, 1e2)
    ax[0].set_ylabel("|G_zz|")
    ax[0].legend(fontsize=8)
    for label, frd in runs.items():
        ax[1].semilogy(frd.freqs, 100 * column_error(frd, truth)[:, 0], lw=0.8, label=label)
    ax[1].set_ylabel("error, Z column [% of peak]")
    ax[1].set_ylim(1e-3, 1e5)
    ax[1].legend(fontsize=8)
    U = np.fft.rfft(exps[0].u[:, 0] - exps[0].u[:, 0].mean())
    k = np.arange(U.size)
    f = k / (exps[0].n_samples * exps[0].dt)
    step = np.angle(U[1:] * np.conj(U[:-1]))  # phase rotation from line k-1 to k
    ax[2].plot(f[1:], np.abs(step), "C2", lw=0.6)
    ax[2].set_ylabel("|phase step of U_z per line| [rad]")
    ax[2].set_xlabel("frequency [Hz]")
    ax[2].set_xscale("log")
    ax[2].set_xlim(0.5, 120)
    fig.suptitle("P-558 chirp-z/rx/ry: the LPM at the chirp's band edges")
    fig.tight_layout()
    fig.savefig(out / "lpm_chirp.png", dpi=100)


if __name__ == "__main__":
    main()
