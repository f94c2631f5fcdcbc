"""The real maglev record (``../shared/data/maglev_closedloop``): what can be concluded without a trusted controller.

The record holds three 3-axis magnetometers and the two PWM commands; no reference signal
was logged and the controller is only "probably" a PD on IIR-filtered bx/by.  This script
measures (1) how much of the record is saturated, (2) whether a linear, time-invariant
controller explains the commands from the measurements (a MISO ARX fit from each
magnetometer's x/y channels to each command on the unsaturated samples, cross-validated
on the second half), and (3) whether anything excites the loop from outside.

    .venv/bin/python studies/closed_loop/maglev_record_study.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "output"
FS = 2700.0


def _load() -> dict:
    import scipy.io as sio

    from stageid.data.datasets import SHARED_DATA

    p = Path(SHARED_DATA or "") / "maglev_closedloop" / "PD_data_with_input.mat"
    if not p.exists():
        raise FileNotFoundError("../shared/data/maglev_closedloop is not available")
    return sio.loadmat(p)


def _arx_fit(
    y: np.ndarray,
    u: np.ndarray | None,
    order: int,
    train: slice,
    test: slice,
    ar: bool = True,
    fir_order: int | None = None,
) -> float:
    """One-step fit percent on ``test`` of a MISO ARX model y <- u (columns), trained on ``train``;
    ``u=None`` gives the AR-only baseline, ``ar=False`` a FIR model from ``u`` alone."""
    from stageid.closedloop.pem import _shifted

    def reg(sl: slice) -> tuple[np.ndarray, np.ndarray]:
        yy = y[sl] - y[sl].mean()
        uu = None if u is None else u[sl] - u[sl].mean(axis=0)
        cols = [-_shifted(yy, order, 1)] if ar else []
        if u is not None:
            cols += [_shifted(uu[:, j], (fir_order or order) + 1, 0) for j in range(uu.shape[1])]
        k0 = max(order, fir_order or 0)
        return np.hstack(cols)[k0:], yy[k0:]

    Phi, Y = reg(train)
    th, *_ = np.linalg.lstsq(Phi, Y, rcond=None)
    Phi_t, Y_t = reg(test)
    e = Y_t - Phi_t @ th  # one-step prediction error (the controller acts on measured data)
    return float(100 * (1 - np.linalg.norm(e) / np.linalg.norm(Y_t - Y_t.mean())))


def run() -> dict:
    OUT.mkdir(parents=True, exist_ok=True)
    d = _load()
    u = np.asarray(d["u"], float)
    start = int(np.argmax(np.any(u != 0, axis=1)))
    u = u[start:]
    sensors = [np.asarray(d[f"rawMeasurements{k}"], float)[start:] for k in (1, 2, 3)]
    sat = np.abs(u) >= 255
    n = u.shape[0]
    # longest unsaturated stretch for the controller fit
    ok = ~np.any(sat, axis=1)
    best, cur = (0, 0), 0
    for k in range(n):
        cur = cur + 1 if ok[k] else 0
        if cur > best[1] - best[0]:
            best = (k - cur + 1, k + 1)
    lo, hi = best
    mid = lo + (hi - lo) // 2
    lines = [
        "# Real maglev record (PD_data_with_input.mat), measured by studies/closed_loop/maglev_record_study.py",
        "",
        f"- samples after the loop starts: {n} ({n / FS:.2f} s at ~{FS:g} Hz); saturated commands: "
        f"u1 {100 * sat[:, 0].mean():.1f} %, u2 {100 * sat[:, 1].mean():.1f} %; longest unsaturated stretch {hi - lo} samples.",
        "- no reference signal was recorded: nothing external excites the loop, so the closed-loop transfer T of eq. 11 "
        "(reference -> output) cannot be identified and eq. 18 cannot be applied, whatever the controller.",
        "",
        "Linear controller check: one-step fit [%] of ARX(order 4) from a magnetometer's x/y channels to each command "
        "(trained on the first half of the unsaturated stretch, tested on the second):",
        "",
        "| model | u1 | u2 |",
        "|---|---|---|",
    ]
    fits = {}
    base = [_arx_fit(u[:, j], None, 4, slice(lo, mid), slice(mid, hi)) for j in range(2)]
    lines.append(f"| AR(4) of the command alone (baseline) | {base[0]:.2f} | {base[1]:.2f} |")
    for k, s in enumerate(sensors, start=1):
        row = [_arx_fit(u[:, j], s[:, :2], 4, slice(lo, mid), slice(mid, hi)) for j in range(2)]
        fir = [_arx_fit(u[:, j], s[:, :2], 4, slice(lo, mid), slice(mid, hi), ar=False, fir_order=30) for j in range(2)]
        fits[k] = row + fir
        lines.append(f"| ARX(4) with sensor {k} x/y | {row[0]:.2f} | {row[1]:.2f} |")
        lines.append(f"| FIR(30) from sensor {k} x/y only | {fir[0]:.2f} | {fir[1]:.2f} |")
    lines += [
        "",
        "Reading: a high fit means the commands are (close to) a linear function of that sensor's recent samples, i.e. a "
        "controller model could be estimated from the data instead of trusted; it does not identify the plant, because "
        "with no external excitation the plant input is itself a function of the measured output (the direct method then "
        "returns the inverse controller, -1/M, not G).",
        "",
    ]
    (OUT / "maglev_record_summary.md").write_text("\n".join(lines))
    return {"fits": fits, "saturation": sat.mean(axis=0), "text": "\n".join(lines)}


if __name__ == "__main__":
    print(run()["text"])
