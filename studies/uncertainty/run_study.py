"""Calibration of the uncertainty of the realised Hankel-MAP model and of FRD fits (issue 20).

For every noise seed a record is simulated, the model identified and its
``response_uncertainty`` compared with the truth: ``|G_est - G_true| <= 1.73 std`` holds 95 %
of the time for a circular complex Gaussian error of variance ``std^2``; ``E|err|^2 / std^2``
is 1 for a calibrated std.  Cases:

* ``p558``: the P-558 reference (Cao & Chen eq. 23-25, 15 states), all inputs band-limited
  1-100 Hz at once, 20 000 samples, 1 % output noise, ``HankelMAP(order=15)`` (horizon auto);
* ``p558-channels``: the same stage from the paper's three chirp records (one per input,
  ``per_channel=True``, orders 7, 4, 4, horizon auto or ``--horizon=P``), eq. 19-22;
* ``random``: random 1x2 stages with two resonances (``tests/_subspace_systems.random_stage``,
  seeds 8 and 9), not used to develop the method;
* ``random-mimo``: random 2x2 stages with four lightly damped resonances (seeds 21 and 22, as
  ``tests/test_subspace_estimator.py``), 20 000 samples, 1 % noise, order 8, horizon auto;
* ``frd``: a 1x2 two-mode plant's FRF with a known per-line std (2 % of the peak, times
  0.5-1.5), ``FRDIdentification(order=4)``; ``frd-residual``: the same without the std.

    .venv/bin/python studies/uncertainty/run_study.py [n_seeds] [case ...] [--horizon=P]
        [--overlap=exact|inflate] [--bias=local|none] [--columns=N] [--grid=modes|even]
        [--first-seed=K] [--stage-offset=K]

``--bias`` is the realisation-misfit term of the Hankel-MAP bands (default ``local``, as the
library), ``--columns`` the exact covariance's column cap (``MAX_OVERLAP_COLUMNS``), ``--grid``
the placement of its frequencies (default ``modes``, as the library; ``even`` the former grid).

Writes ``output/<case>.json`` (per seed, per entry) and prints a summary table.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.models import StateSpaceModel
from stageid.plants import piezo_stage as ps
from stageid.subspace import HankelMAP
from stageid.subspace.uncertainty import realised_response_uncertainty

sys.path.insert(0, str(Path(__file__).parents[2] / "tests"))
from _subspace_systems import band_limited, random_stage, record  # noqa: E402

OUT = Path(__file__).parent / "output"
FRDResultTypes = ()  # set in main: the FRD result class (its uncertainty has no overlap rule)
K95 = 1.73
FREQS = np.geomspace(1.5, 98.0, 200)  # inside the excited 1-100 Hz band
#: Horizon of the per-channel case: "auto", or an integer from the command line (--horizon=16).
HORIZON: int | str = "auto"
#: Eq. 9 covariance of the Hankel-MAP cases (--overlap=exact|inflate; default "auto" = exact).
OVERLAP = "auto"
#: The realisation-misfit bias term of the Hankel-MAP cases (--bias=local|none).
BIAS = "local"
#: Placement of the exact covariance's frequencies (--grid=modes|even).
GRID = "modes"
#: Suffix of the output file (the column cap, when ``--columns=N`` is given).
TAG = ""
#: Noise seeds are FIRST_SEED .. FIRST_SEED + n - 1 (--first-seed=K: fresh noise on the same stages).
FIRST_SEED = 0
#: Added to the random stages' seeds (--stage-offset=K: stages no one has looked at).
STAGE_OFFSET = 0


def p558(seed: int):
    g = ps.model()
    exp = record(g, band_limited(20000, 3, g.dt, seed) * np.array([10.0, 100.0, 100.0]), 0.01, seed)
    t = time.perf_counter()
    res = HankelMAP(order=15).fit(exp)
    t_fit = time.perf_counter() - t
    return g, res, t_fit


def p558_channels(seed: int):
    exps = [ps.EXPERIMENTS[k](seed) for k in ("chirp-z", "chirp-rx", "chirp-ry")]
    t = time.perf_counter()
    res = HankelMAP(order=[7, 4, 4], per_channel=True, horizon=HORIZON).fit(exps)
    return ps.model(), res, time.perf_counter() - t


def random_case(seed: int):
    g = random_stage(STAGE_OFFSET + 8 + seed % 2, m=1, q=2, modes=2)
    exp = record(g, band_limited(6000, 1, g.dt, seed), 0.02, seed, names=False)
    t = time.perf_counter()
    res = HankelMAP(horizon=25, order=4).fit(exp)
    return g, res, time.perf_counter() - t


def random_mimo(seed: int):
    g = random_stage(STAGE_OFFSET + 21 + seed % 2)  # 2x2, four resonances at 8-90 Hz, 0.5-3 % damping
    exp = record(g, band_limited(20000, 2, g.dt, seed), 0.01, seed, names=False)
    t = time.perf_counter()
    res = HankelMAP(order=g.n_states).fit(exp)
    return g, res, time.perf_counter() - t


def random_siso(seed: int):
    # unseen: SISO stages with three resonances, 8000 samples, 3 % noise (seeds 31-32)
    g = random_stage(STAGE_OFFSET + 31 + seed % 2, m=1, q=1, modes=3)
    exp = record(g, band_limited(8000, 1, g.dt, seed), 0.03, seed, names=False)
    t = time.perf_counter()
    res = HankelMAP(order=g.n_states).fit(exp)
    return g, res, time.perf_counter() - t


def random_3x2(seed: int):
    # unseen: 3 outputs, 2 inputs, three resonances, 12000 samples, 1 % noise (seeds 41-42)
    g = random_stage(STAGE_OFFSET + 41 + seed % 2, m=2, q=3, modes=3)
    exp = record(g, band_limited(12000, 2, g.dt, seed), 0.01, seed, names=False)
    t = time.perf_counter()
    res = HankelMAP(order=g.n_states).fit(exp)
    return g, res, time.perf_counter() - t


def two_mode_plant() -> StateSpaceModel:
    A, B, C = np.zeros((4, 4)), np.zeros((4, 1)), np.zeros((2, 4))
    for i, (f, z, c) in enumerate([(12.0, 0.03, [1.0, 0.5]), (47.0, 0.02, [0.3, -0.8])]):
        w = 2 * np.pi * f
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[0, 1], [-w * w, -2 * z * w]]
        B[2 * i + 1, 0] = w * w
        C[:, 2 * i] = c
    return StateSpaceModel(A, B, C, np.zeros((2, 1)), None).c2d(0.002)


def frd_case(seed: int, with_std: bool = True):
    g = two_mode_plant()
    f = np.linspace(1, 200, 300)
    Gt = g.frequency_response(f)
    sd = 0.02 * np.abs(Gt).max() * (0.5 + np.random.default_rng(0).random(Gt.shape))
    rng = np.random.default_rng([seed, 7])
    noise = sd * (rng.standard_normal(Gt.shape) + 1j * rng.standard_normal(Gt.shape)) / np.sqrt(2)
    t = time.perf_counter()
    res = FRDIdentification(order=4, sample_time=g.dt).fit(FrequencyResponse(f, Gt + noise, sd if with_std else None))
    return g, res, time.perf_counter() - t


CASES = {
    "p558": p558,
    "p558-channels": p558_channels,
    "random": random_case,
    "random-mimo": random_mimo,
    "random-siso": random_siso,
    "random-3x2": random_3x2,
    "frd": frd_case,
    "frd-residual": lambda seed: frd_case(seed, False),
}


def run(case: str, n_seeds: int) -> dict:
    z, ratio, t_fit, t_unc = [], [], [], []
    for seed in range(FIRST_SEED, FIRST_SEED + n_seeds):
        g, res, tf = CASES[case](seed)
        t = time.perf_counter()
        if isinstance(res, FRDResultTypes):
            fr = res.response_uncertainty(FREQS)
        else:
            fr = realised_response_uncertainty(res, FREQS, overlap=OVERLAP, bias=BIAS, grid=GRID)
        t_unc.append(time.perf_counter() - t)
        t_fit.append(tf)
        err = np.abs(fr.response - g.frequency_response(FREQS))
        z.append(err / fr.std)
        ratio.append((err**2, fr.std**2))
    Z = np.array(z)  # (seeds, freqs, q, m)
    e2 = np.array([r[0] for r in ratio])
    s2 = np.array([r[1] for r in ratio])
    names = [(o, i) for o in fr.outputs for i in fr.inputs]
    per_entry = {
        f"{i}->{o}": float(np.mean(Z[:, :, a, b] <= K95))
        for a, o in enumerate(fr.outputs)
        for b, i in enumerate(fr.inputs)
    }
    low, high = FREQS < 10, FREQS > 60
    summary = {
        "case": case,
        "seeds": n_seeds,
        "coverage": float(np.mean(Z <= K95)),
        "coverage_per_entry": per_entry,
        "coverage_below_10hz": float(np.mean(Z[:, low] <= K95)),
        "coverage_above_60hz": float(np.mean(Z[:, high] <= K95)),
        "mean_err2_over_std2": float(np.mean(e2) / np.mean(s2)),
        "median_rms_ratio": float(np.median(np.sqrt(e2.mean(0) / s2.mean(0)))),
        "coverage_if_std_x3": float(np.mean(Z <= 3 * K95)),
        "coverage_if_std_div3": float(np.mean(Z <= K95 / 3)),
        "fit_s_median": float(np.median(t_fit)),
        "uncertainty_s_median": float(np.median(t_unc)),
        "entries": [f"{i}->{o}" for o, i in names],
    }
    OUT.mkdir(exist_ok=True)
    summary["overlap"] = OVERLAP
    (OUT / f"{case}-{OVERLAP}{TAG}.json").write_text(json.dumps(summary, indent=1))
    return summary


def main() -> None:
    global HORIZON, OVERLAP, FRDResultTypes, TAG, BIAS, GRID, FIRST_SEED, STAGE_OFFSET
    from stageid.frf.identification import FRDResult

    FRDResultTypes = (FRDResult,)
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    for a in sys.argv[1:]:
        if a.startswith("--horizon="):
            HORIZON = int(a.split("=", 1)[1])
        if a.startswith("--overlap="):
            OVERLAP = a.split("=", 1)[1]
        if a.startswith("--bias="):
            BIAS = a.split("=", 1)[1]
            TAG += f"-bias-{BIAS}"
        if a.startswith("--grid="):
            GRID = a.split("=", 1)[1]
            TAG += f"-grid-{GRID}"
        if a.startswith("--first-seed="):
            FIRST_SEED = int(a.split("=", 1)[1])
            TAG += f"-from{FIRST_SEED}"
        if a.startswith("--stage-offset="):
            STAGE_OFFSET = int(a.split("=", 1)[1])
            TAG += f"-stages+{STAGE_OFFSET}"
        if a.startswith("--columns="):  # the exact covariance's column cap (default MAX_OVERLAP_COLUMNS)
            import stageid.subspace.uncertainty as unc

            unc.MAX_OVERLAP_COLUMNS = int(a.split("=", 1)[1])
            TAG += f"-{unc.MAX_OVERLAP_COLUMNS}col"
    n = int(args[0]) if args else 20
    cases = args[1:] or list(CASES)
    for case in cases:
        s = run(case, n)
        print(
            f"{case:14s} seeds {n}: coverage {100 * s['coverage']:.1f} % (<10 Hz {100 * s['coverage_below_10hz']:.1f}, "
            f">60 Hz {100 * s['coverage_above_60hz']:.1f}), E|err|^2/std^2 {s['mean_err2_over_std2']:.2f}, "
            f"median rms ratio {s['median_rms_ratio']:.2f}; fit {s['fit_s_median']:.2f} s, "
            f"uncertainty {s['uncertainty_s_median']:.2f} s",
            flush=True,
        )
        print("   per entry:", ", ".join(f"{k} {100 * v:.0f}" for k, v in s["coverage_per_entry"].items()), flush=True)


if __name__ == "__main__":
    main()
