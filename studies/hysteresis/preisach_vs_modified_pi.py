"""Preisach vs modified PI on the reference actuator and on a fine asymmetric Preisach actuator.

Run: ``python studies/hysteresis/preisach_vs_modified_pi.py``; prints max errors in % of range
(identification record, then validation records, each with its own fitted output offset).
"""

import time

import numpy as np

from stageid.hysteresis import PIIdentifier, PreisachIdentifier, PreisachModel
from stageid.plants.piezo_actuator import EXPERIMENTS


def fine_preisach(n=200):
    """Rate-independent, asymmetric, not PI: a smooth skewed Gaussian relay density on 200 levels."""
    v = (np.arange(n) + 0.5) / n * 1000 - 500
    a, b = np.meshgrid(v, v, indexing="ij")
    centre, half = (a + b) / 2, (a - b) / 2
    dens = np.exp(-((half / 120) ** 2)) * np.exp(-(((centre - 80) / 350) ** 2)) * (1 + 0.6 * np.tanh(centre / 200))
    dens += np.eye(n) * 0.05 * (1 + 0.5 * v / 500)  # reversible part, asymmetric
    w = dens[np.tril_indices(n)]
    return PreisachModel((-500.0, 500.0), w / w.sum() * 3.0)


def max_err(model, u, y):
    m = model.with_state(model.consistent_state(u[0]))
    yh = m.simulate(u)[:, 0]
    e = yh + np.mean(y - yh) - y
    return 100 * np.max(np.abs(e)) / np.ptp(y)


def compare(name, records):
    train, *valid = records
    for label, est in (
        ("modified-pi 20", PIIdentifier("modified-pi", n_operators=20)),
        ("preisach 20", PreisachIdentifier(n_levels=20)),
    ):
        t = time.perf_counter()
        model = est.fit(train).model
        dt = time.perf_counter() - t
        errs = [max_err(model, e.u[:, 0], e.y[:, 0]) for e in records]
        print(f"{name:18s} {label:15s} fit {dt:5.2f} s  max error % " + " ".join(f"{x:.3f}" for x in errs))


keys = ("decaying-triangle", "triangle-1hz", "decaying-sine")
compare("piezo_actuator", [EXPERIMENTS[k](seed=0) for k in keys])
plant = fine_preisach()
recs = []
for k in keys:
    e = EXPERIMENTS[k](seed=0)
    u = e.u[:, 0]
    recs.append(e.with_(y=plant.with_state(plant.consistent_state(u[0])).simulate(u)))
compare("fine preisach", recs)
u = EXPERIMENTS["decaying-triangle"](seed=0).u[:, 0]
m = PreisachIdentifier(n_levels=20).fit(recs[0]).model
pi = PIIdentifier("pi", n_operators=20).fit(recs[0]).model
for label, mod in (("preisach 20 simulate", m), ("pi 20 simulate", pi)):
    mod.simulate(u)
    t = time.perf_counter()
    for _ in range(20):
        mod.simulate(u)
    print(f"{label}: {(time.perf_counter() - t) / 20 * 1e3:.2f} ms for {len(u)} samples")
