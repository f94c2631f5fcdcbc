"""The real maglev record without a trusted controller: the direct route, its checks, and the guessed PD.

``../shared/data/maglev_closedloop``: three 3-axis magnetometers, two PWM commands saturated at
+-255, ~2700 Hz, no reference logged; the controller is "probably" a PD (Kp = 450, Kd = 2) on
IIR-filtered bx/by (ALPHA = 0.06, DALPHA = 0.03).  This script asks:

1. does the guessed PD explain the logged commands (a few plausible readings of the guess, and
   the gains a least-squares fit of the same structure prefers), on unsaturated samples;
2. what the direct prediction-error route says about the plant u -> (bx, by) of magnetometer 1:
   order, unstable poles with +-2 std bands, the checks (excitation above all), and whether the
   two halves of the record agree;
3. whether the identified plant is the plant or the inverse of the controller, which is what a
   record without external excitation tends to give: the loop closed by the identified plant and
   the guessed PD, and the identified plant against -1 / PD.

    OMP_NUM_THREADS=1 .venv/bin/python studies/closed_loop/maglev_unknown_controller.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.signal import lfilter

FS = 2700.0
KP, KD, ALPHA, DALPHA = 450.0, 2.0, 0.06, 0.03
START = 3400  # the commands are zero before the loop starts


def load() -> tuple[np.ndarray, np.ndarray]:
    import scipy.io as sio

    from stageid.data.datasets import SHARED_DATA

    p = Path(SHARED_DATA or "") / "maglev_closedloop" / "PD_data_with_input.mat"
    if not p.exists():
        raise SystemExit("../shared/data/maglev_closedloop is not available")
    d = sio.loadmat(p)
    return d["u"][START:].astype(float), d["rawMeasurements1"][START:, :2].astype(float)


def guessed_pd(b: np.ndarray, kp: float, kd: float, per_second: bool, sign: float) -> np.ndarray:
    """u = sign (kp bf + kd dbf): bf = IIR(ALPHA) of b, dbf = IIR(DALPHA) of the difference of bf."""
    bf = lfilter([ALPHA], [1, -(1 - ALPHA)], b - b[:200].mean(axis=0), axis=0)
    d = np.diff(bf, axis=0, prepend=bf[:1]) * (FS if per_second else 1.0)
    dbf = lfilter([DALPHA], [1, -(1 - DALPHA)], d, axis=0)
    return np.clip(sign * (kp * bf + kd * dbf), -255, 255), bf, dbf


def fit_percent(u: np.ndarray, u_hat: np.ndarray, keep: np.ndarray) -> np.ndarray:
    e = u[keep] - u_hat[keep]
    c = u[keep] - u[keep].mean(axis=0)
    return 100 * (1 - np.linalg.norm(e, axis=0) / np.linalg.norm(c, axis=0))


def pd_consistency(u: np.ndarray, b: np.ndarray) -> list[str]:
    keep = np.all(np.abs(u) < 254.5, axis=1)
    keep[:500] = False  # the filters' start
    lines = ["| reading of the guess | fit u1 % | fit u2 % |", "|---|---|---|"]
    for per_second in (False, True):
        for sign in (1.0, -1.0):
            u_hat, bf, dbf = guessed_pd(b, KP, KD, per_second, sign)
            f = fit_percent(u, u_hat, keep)
            what = f"{'+' if sign > 0 else '-'}(Kp bf + Kd dbf), derivative per {'second' if per_second else 'sample'}"
            lines.append(f"| {what} | {f[0]:.1f} | {f[1]:.1f} |")
    _, bf, dbf = guessed_pd(b, 1.0, 1.0, True, 1.0)
    for j in range(2):  # the gains the record prefers for the same structure, plus an offset
        X = np.column_stack([bf[keep, j], dbf[keep, j], np.ones(keep.sum())])
        th = np.linalg.lstsq(X, u[keep, j], rcond=None)[0]
        f = 100 * (1 - np.linalg.norm(u[keep, j] - X @ th) / np.linalg.norm(u[keep, j] - u[keep, j].mean()))
        lines.append(
            f"| least squares, axis {j + 1}: Kp = {th[0]:.4g}, Kd (per second) = {th[1]:.4g}, offset {th[2]:.3g} |"
            + (f" {f:.1f} | |" if j == 0 else f" | {f:.1f} |")
        )
    return lines


def direct_fit(u: np.ndarray, b: np.ndarray, order):
    from stageid.closedloop import DirectPredictionError
    from stageid.data import Experiment

    return DirectPredictionError(order=order).fit(Experiment(u, b, 1.0 / FS, ("u1", "u2"), ("bx1", "by1")))


def main() -> None:
    u, b = load()
    print(f"samples {u.shape[0]}, saturated u1 {100 * np.mean(np.abs(u[:, 0]) >= 254.5):.1f} %, "
          f"u2 {100 * np.mean(np.abs(u[:, 1]) >= 254.5):.1f} %")  # fmt: skip
    print("\n## Guessed PD against the logged commands (unsaturated samples)\n")
    print("\n".join(pd_consistency(u, b)))
    print("\n## Direct route, u -> (bx, by) of magnetometer 1\n")
    whole = direct_fit(u, b, "auto")
    print(whole.summary())
    n = whole.order
    half = u.shape[0] // 2
    halves = [direct_fit(u[:half], b[:half], n), direct_fit(u[half:], b[half:], n)]
    for name, res in zip(("first half", "second half"), halves):
        std = res.unstable_pole_std
        poles = ", ".join(f"{p.real:.4g} +- {2 * s:.2g}" for p, s in zip(res.unstable_poles, std))
        print(f"{name} (order {n}): unstable poles [rad/s] {poles or 'none'}")
    from stageid.closedloop import unstable_pole_agreement

    print(unstable_pole_agreement(halves, rtol=0.1).line())
    print("\n## Plant or inverse controller?\n")
    f = np.geomspace(1.0, 300.0, 40)
    G = whole.plant.frequency_response(f)
    z = np.exp(2j * np.pi * f / FS)
    lp_b = ALPHA / (1 - (1 - ALPHA) / z)
    lp_d = DALPHA / (1 - (1 - DALPHA) / z)
    M = lp_b * (KP + KD * FS * (1 - 1 / z) * lp_d)  # the guessed PD per axis, per-second derivative
    for j in range(2):
        ratio = np.median(np.abs(G[:, j, j] * M))
        print(f"axis {j + 1}: median |G_jj M| over 1-300 Hz = {ratio:.3g} (1 for G = -1/M, the inverse controller)")


if __name__ == "__main__":
    main()
