"""Best linear approximation of a hysteretic piezo stage: simulated truth, then the real records.

Run: ``OMP_NUM_THREADS=1 python studies/bla/bla_study.py``; prints Markdown for RESULTS.md.

A. The reference actuator of :mod:`stageid.plants.piezo_actuator` (asymmetric modified-PI
   hysteresis, then a static quadratic) before a 300 Hz resonance (zeta 0.05), driven by
   random-odd multisines of three RMS levels, 16 realisations x 3 steady periods (+1 transient
   period, detected), output noise 2 nm.  For each level: the BLA's low-frequency gain and
   phase, total over noise variance, the odd and even detection levels, and the estimated
   stochastic distortion variance against a Monte-Carlo truth (200 noise-free realisations).
B. The real records of /work/shared/data: which excitation allows what.
"""

from __future__ import annotations

import numpy as np

from stageid.data import Experiment
from stageid.frf.bla import BLAAccumulator, bla_frf
from stageid.signals import multisine

DT, L, P, M = 2e-4, 4096, 3, 16
BANDS = [(0, 50), (50, 250), (250, 400), (400, 1000)]


def actuator():
    from stageid.plants.piezo_actuator import PiezoActuator

    return PiezoActuator(f_n=300.0, zeta=0.05)


def records(act, rms: float, count: int, first: int, noise: float):
    rng = np.random.default_rng(first + 7)
    for r in range(first, first + count):
        u = multisine(L * (P + 1), DT, 2.0, 1000.0, seed=5, realisation=r, n_periods=P + 1, lines="random-odd", rms=rms)
        y = act.simulate(u, DT)[:, 0] + noise * rng.standard_normal(u.size)
        yield Experiment(u, y, DT, ("V",), ("y",))


def simulated() -> list[str]:
    act = actuator()
    rows = [
        "| RMS drive [V] | BLA at 2.4 Hz [nm/V], phase [deg] | total / noise variance (median) | odd lines | even lines | "
        "estimated / Monte-Carlo distortion variance per band (" + ", ".join(f"{a}-{b} Hz" for a, b in BANDS) + ") |",
        "|---|---|---|---|---|---|",
    ]
    for rms in (30.0, 100.0, 250.0):
        res = bla_frf(records(act, rms, M, 0, 0.002))
        truth = bla_frf(records(act, rms, 200, 1000, 0.0))
        f = res.frd
        g = f.response[0, 0, 0]
        ratio_db = 10 * np.log10(np.median(f.total_std**2 / f.std**2))
        est, ref = res.stochastic_variance[:, 0, 0], truth.stochastic_variance[:, 0, 0]
        per_band = []
        for lo, hi in BANDS:
            band = (f.freqs >= lo) & (f.freqs < hi)
            per_band.append(f"{np.mean(est[band] / ref[band]):.2f}")
        rows.append(
            f"| {rms:g} | {1000 * abs(g):.2f}, {np.degrees(np.angle(g)):.1f} | {ratio_db:+.1f} dB | "
            f"{res.odd.level_db[0]:+.1f} dB{' (flagged)' if res.odd.detected[0] else ''} | "
            f"{res.even.level_db[0]:+.1f} dB{' (flagged)' if res.even.detected[0] else ''} | {', '.join(per_band)} |"
        )
    return rows


def real_sine() -> list[str]:
    """The 150 V 1 Hz sine (smarthysteresis): one excited line, its harmonics as detection lines."""
    from stageid.data.datasets import load_smarthysteresis, shared_data_dir

    root = shared_data_dir()
    path = None if root is None else root / "piezo_smarthysteresis" / "hysteresis_v_150_1hz.csv"
    if path is None or not path.exists():
        return ["The smarthysteresis record is not here; part B skipped."]
    e = load_smarthysteresis(path)
    u, y = e.u[:, 0], e.y[:, 0]
    start = int(np.argmax(np.abs(u - u[0]) > 1.0))  # the sine starts after an idle stretch
    period = 5000  # 1 Hz at 0.2 ms: the rising zero crossings are exactly 5000 samples apart
    n = (u.size - start) // period
    rec = Experiment(u[start : start + n * period], y[start : start + n * period], e.dt, ("V",), ("y",))
    acc = BLAAccumulator(periods=n, excited=[1], detection_odd=range(3, 40, 2), detection_even=range(2, 40, 2))
    acc.add(rec)
    res = acc.result()
    g = res.frd.response[0, 0, 0]
    odd_h = np.sqrt(res.odd.power[:3, 0])
    even_h = np.sqrt(res.even.power[:3, 0])
    y1 = abs(g) * abs(np.fft.rfft(rec.u[:period, 0])[1])
    return [
        f"{n} periods of 5000 samples from sample {start}; {res.transient_periods} transient period(s) dropped, "
        f"{res.n_periods} averaged.",
        f"First harmonic: {abs(g):.4f} um/V at {np.degrees(np.angle(g)):.1f} deg (the lag is the hysteresis).",
        f"Odd harmonics 3, 5, 7 at {', '.join(f'{100 * h / y1:.2f}' for h in odd_h)} % of the fundamental; "
        f"even 2, 4, 6 at {', '.join(f'{100 * h / y1:.2f}' for h in even_h)} %.",
        f"Detection levels over the period-to-period noise: odd {res.odd.level_db[0]:+.1f} dB "
        f"({'flagged' if res.odd.detected[0] else 'not flagged'}), even {res.even.level_db[0]:+.1f} dB "
        f"({'flagged' if res.even.detected[0] else 'not flagged'}).",
    ]


def main() -> None:
    print("## A. Reference actuator (modified-PI hysteresis + quadratic) before a 300 Hz resonance\n")
    print("\n".join(simulated()))
    print("\n## B. Real piezo records\n")
    print("\n".join(f"- {line}" for line in real_sine()))


if __name__ == "__main__":
    main()
