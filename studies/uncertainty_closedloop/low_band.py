"""Why the closed-loop bands are too narrow at the low end of the band, and the "local" bias rule.

Reads the seeds ``run_study.py`` cached in ``output/<plant>_seed<k>.pkl`` (run that first) and,
per frequency of the band, compares for the returned (reduced) plant ``P_r``, the deduced
response ``P = T (M - M T)^-1`` before the reduction and the truth ``G``:

* the relative errors ``|P - G| / |G|`` (deduction) and ``|P_r - G| / |G|`` (returned model);
* the reduction's relative misfit ``|P_r - P| / |P|`` (what the bias rules see);
* the amplification of eq. 18, ``||(I + G M)|| ||(M - M T)^-1||`` (largest singular values);
* the std of the bias rules ``flat``, ``local`` and ``inflate`` over ``|G|``, and their coverage
  (``|err| <= 1.73 std``) by quarter of the band.

    .venv/bin/python studies/uncertainty_closedloop/low_band.py [plant]

Writes ``low_band_<plant>.png`` beside this script and prints the tables of RESULTS.md.
"""

from __future__ import annotations

import dataclasses
import pickle
import sys
from pathlib import Path

import numpy as np

from stageid.closedloop.uncertainty import deduction_sensitivity, plant_uncertainty

sys.path.insert(0, str(Path(__file__).parent))
from run_study import BAND, PLANTS  # noqa: E402

HERE = Path(__file__).parent
RULES = ("flat", "local", "inflate")


def main() -> None:
    name = sys.argv[1] if len(sys.argv) > 1 else "maglev"
    paths = sorted((HERE / "output").glob(f"{name}_seed*.pkl"))
    if not paths:
        raise SystemExit(f"no cached seeds in {HERE / 'output'}: run run_study.py first")
    f = np.geomspace(*BAND, 200)
    true_model = PLANTS[name][2]()
    truth = true_model.frequency_response(f)
    rel = {k: [] for k in ("deduced", "returned", "misfit", "amplification")}
    err2, std2 = [], {r: [] for r in RULES}
    for path in paths:
        fitted = pickle.loads(path.read_bytes())
        res = dataclasses.replace(fitted["result"], covariance=fitted["sandwich"])
        L, R, _, P = deduction_sensitivity(res, f)
        G = res.plant.frequency_response(f)
        # the deduction is discrete: compare it with the ZOH equivalents of the truth and of P_r
        truth_d = true_model.c2d(res.dt).frequency_response(f) if true_model.dt is None else truth
        G_d = res.plant.c2d(res.dt).frequency_response(f) if res.plant.dt is None else G
        mag = np.abs(truth)
        rel["deduced"].append(np.abs(P - truth_d) / np.abs(truth_d))
        rel["returned"].append(np.abs(G - truth) / mag)
        rel["misfit"].append(np.abs(G_d - P) / np.abs(P))
        # relative amplification of eq. 18: ||dG|| / ||G|| <= kappa ||dT|| / ||T||
        T = P @ np.linalg.inv(R)
        kappa = (
            np.linalg.norm(L, 2, axis=(1, 2)) * np.linalg.norm(R, 2, axis=(1, 2)) * np.linalg.norm(T, 2, axis=(1, 2))
        )
        rel["amplification"].append(kappa / np.linalg.norm(P, 2, axis=(1, 2)))
        err2.append(np.abs(G - truth) ** 2)
        for rule in RULES:
            std2[rule].append(plant_uncertainty(res, f, rule).std ** 2)
    E = np.array(err2)  # (seeds, f, p, p)
    quarters = np.array_split(np.arange(f.size), 4)
    print(f"{name}: {len(paths)} seeds")
    print("| rule | " + " | ".join(f"{f[k[0]]:.0f}-{f[k[-1]]:.0f} Hz" for k in quarters) + " | band | mean e^2/std^2 |")
    print("|---|" + "---|" * 6)
    for rule in RULES:
        S = np.array(std2[rule])
        hit = np.sqrt(E) <= 1.73 * np.sqrt(S)
        cells = " | ".join(f"{100 * hit[:, k].mean():.1f} %" for k in quarters)
        print(f"| {rule} | {cells} | {100 * hit.mean():.1f} % | {np.mean(E / S):.2f} |")
    # per-frequency medians over seeds and entries, for the figure and the text
    med = {
        k: np.median(np.array(v).reshape(len(paths), f.size, -1), axis=(0, 2))
        for k, v in rel.items()
        if k != "amplification"
    }
    amp = np.median(np.array(rel["amplification"]), axis=0)
    rms_ratio = {r: np.sqrt(E.mean(axis=(0, 2, 3)) / np.array(std2[r]).mean(axis=(0, 2, 3))) for r in RULES}
    print("\n| quarter | deduced |P-G|/|G| | returned |P_r-G|/|G| | misfit |P_r-P|/|P| | amplification |")
    print("|---|---|---|---|---|")
    for k in quarters:
        print(
            f"| {f[k[0]]:.0f}-{f[k[-1]]:.0f} Hz | {np.median(med['deduced'][k]):.2e} | {np.median(med['returned'][k]):.2e} "
            f"| {np.median(med['misfit'][k]):.2e} | {np.median(amp[k]):.1f} |"
        )
    _figure(name, f, med, amp, rms_ratio)


def _figure(name, f, med, amp, rms_ratio) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    a.loglog(f, med["deduced"], label="deduced P: |P - G| / |G|")
    a.loglog(f, med["returned"], label="returned P_r: |P_r - G| / |G|")
    a.loglog(f, med["misfit"], "--", label="reduction misfit |P_r - P| / |P|")
    a.set_xlabel("frequency [Hz]")
    a.set_ylabel("relative error (median over seeds and entries)")
    a2 = a.twinx()
    a2.loglog(f, amp, color="0.5", lw=0.8, label="eq. 18 amplification")
    a2.set_ylabel("||I + G M|| ||(M - M T)^-1|| ||T|| / ||G||", color="0.4")
    a.legend(fontsize=8, loc="upper right")
    a.set_title(f"{name}: where the returned plant's error comes from")
    for rule, r in rms_ratio.items():
        b.semilogx(f, r, label=f"bias={rule}")
    b.axhline(1.0, color="k", lw=0.6)
    b.set_xlabel("frequency [Hz]")
    b.set_ylabel("rms |err| / rms std over seeds and entries")
    b.set_title("calibration by frequency (1 = calibrated, > 1 too narrow)")
    b.legend()
    fig.tight_layout()
    fig.savefig(HERE / f"low_band_{name}.png", dpi=90)


if __name__ == "__main__":
    main()
