"""Calibration of the PI weight uncertainty (issue 20, point 4) and the loop band on the piezo actuator.

1. Known weights: an 8-operator classical PI in the identified class exactly (thresholds
   ``i R / n`` on a symmetric decaying triangle), output noise 1 % of the range, white or AR(1)
   with pole 0.9 / 0.95 (unit variance), 20 seeds.  Coverage of ``|w_hat - w| <= 1.96 std``
   over the weights and of the noise-free output by the loop's 1.96-std band; ``E e^2 / std^2``
   should be 1.
2. The simulated piezo actuator of the demo (20 operators, classical and modified PI): the
   loop with its band (``loop_band.png``) and the band's width against the model error.

    .venv/bin/python studies/uncertainty_closedloop/hysteresis_weights.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.signal as ss

from stageid.hysteresis import PIIdentifier, PIModel
from stageid.hysteresis.identify.weight_uncertainty import plot_loop_band
from stageid.plants.piezo_actuator import EXPERIMENTS
from stageid.signals import decaying_triangle

HERE = Path(__file__).parent
U = decaying_triangle(1.0, 8, 1e-3, amplitude=10.0)
W_TRUE = np.array([1.0, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05, 0.05])
TRUE = PIModel(r=np.arange(8) * 10.0 / 8, weights=W_TRUE)
Y0 = TRUE.simulate(U).reshape(-1)


def known_weights(ar: float, method: str, n_seeds: int = 20) -> str:
    hits, z2, band = [], [], []
    for seed in range(n_seeds):
        v = ss.lfilter([np.sqrt(1 - ar**2)], [1, -ar], np.random.default_rng(seed).standard_normal(U.size))
        fit = PIIdentifier("pi", n_operators=8, initial_state="zero", weight_uncertainty=method).fit(
            (U, Y0 + 0.01 * np.ptp(Y0) * v)
        )
        wu = fit.weight_uncertainty
        e = fit.model.weights - W_TRUE
        hits.append(np.abs(e) <= 1.96 * wu.std)
        z2.append(e**2 / wu.std**2)
        y, s = wu.output_band(fit.model, U)
        band.append(np.abs(y - Y0) <= 1.96 * s)
    return (
        f"| {method} | AR {ar:g} | {100 * np.mean(hits):.1f} % | {np.mean(z2):.2f} | {100 * np.mean(band):.1f} % "
        f"| {wu.n_blocks} |"
    )


def actuator() -> None:
    ident = EXPERIMENTS["decaying-triangle"](seed=0)
    valid = EXPERIMENTS["triangle-1hz"](seed=1)
    for kind in ("pi", "modified-pi"):
        fit = PIIdentifier(kind, n_operators=20, weight_uncertainty="auto").fit(ident)
        wu = fit.weight_uncertainty
        y, s = wu.output_band(fit.model, valid.u)
        err = valid.y[:, 0] - y
        rng = np.ptp(valid.y)
        print(
            f"{kind}: method {wu.method}, {wu.n_blocks} blocks; on the validation triangle the band's half-width "
            f"1.96 std is median {100 * np.median(1.96 * s) / rng:.3f} % / max {100 * np.max(1.96 * s) / rng:.3f} % "
            f"of range, the model error max {100 * np.max(np.abs(err)) / rng:.3f} % of range"
        )
        if kind == "modified-pi":
            fig = plot_loop_band(
                fit.model, wu, valid.u, valid.y, xlabel="V [V]", ylabel="y [um]", title="modified PI, validation"
            )
            fig.savefig(HERE / "loop_band.png", dpi=90)


def main() -> None:
    print("| method | noise | weights within 1.96 std | mean e^2/std^2 | loop band covers | blocks |")
    print("|---|---|---|---|---|---|")
    for ar in (0.0, 0.9, 0.95):
        print(known_weights(ar, "sandwich"), flush=True)
    print(known_weights(0.9, "bootstrap", n_seeds=10), flush=True)
    actuator()


if __name__ == "__main__":
    main()
