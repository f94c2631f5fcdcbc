"""Preisach vs modified PI on rate-independent actuators that are not PI models.

Run: ``OMP_NUM_THREADS=1 python studies/hysteresis/preisach_vs_modified_pi.py``; prints a
Markdown summary (quoted in ``studies/hysteresis/RESULTS.md`` section 4b).

Actuators (all rate independent; identification on a 1 Hz decaying triangle at 1 kHz,
validation on a 1 Hz triangle and a decaying 0.5 Hz sine, the letter's experiments of
``stageid.plants.piezo_actuator``):

* ``piezo_actuator``: the repository's reference actuator (coupled plays + a static quadratic);
* ``mild preisach``: the relay actuator of ``stage_study.py`` (160 x 160 point relays over
  +-100 V, weights ``exp(-((a - b) / 0.6)^2) (1 + 0.3 (a + b))``, plus 0.02 um/V reversible),
  without its resonance -- asymmetric, not PI, and the modified PI fits it to about 2 %;
* ``skewed preisach``: 200 x 200 relays over +-500 V with a skewed Gaussian density and an
  asymmetric reversible part, much further from a PI model.

Errors: max |model - record| in % of the record's output range, each record with its own
fitted output offset (mean residual), the model started demagnetised at the record's first
input.  Tracking: the identified model's inverse (exact for the Preisach model, per-sample
monotone inversion for the modified PI) drives the actuator along a 1 Hz triangle over the
middle 80 % of the output range; error after the first cycle in % of full-scale range.
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from stage_study import PreisachActuator  # noqa: E402

from stageid.hysteresis import (  # noqa: E402
    Compensator,
    PIIdentifier,
    PreisachCompensator,
    PreisachIdentifier,
    PreisachModel,
)
from stageid.plants.piezo_actuator import EXPERIMENTS  # noqa: E402
from stageid.signals import triangle  # noqa: E402

KEYS = ("decaying-triangle", "triangle-1hz", "decaying-sine")


def skewed_preisach(n=200):
    """Rate-independent, asymmetric, not PI: a skewed Gaussian density on a 200-cell grid."""
    v = (np.arange(n) + 0.5) / n * 1000 - 500
    a, b = np.meshgrid(v, v, indexing="ij")
    centre, half = (a + b) / 2, (a - b) / 2
    dens = np.exp(-((half / 120) ** 2)) * np.exp(-(((centre - 80) / 350) ** 2)) * (1 + 0.6 * np.tanh(centre / 200))
    dens += np.eye(n) * 0.05 * (1 + 0.5 * v / 500)  # reversible part, asymmetric
    w = dens[np.tril_indices(n)]
    return PreisachModel((-500.0, 500.0), w / w.sum() * 3.0)


class Mild:
    """``stage_study.PreisachActuator`` (rate independent), driven in its +-100 V range."""

    scale = 0.19  # the letter's +-500 V inputs -> +-95 V

    def __init__(self):
        self.act = PreisachActuator()

    def __call__(self, u):
        return self.act.simulate(u)


def skewed_plant():
    model = skewed_preisach()
    return lambda u: model.with_state(model.consistent_state(u[0])).simulate(u)[:, 0]


def max_err(model, u, y):
    m = model.with_state(model.consistent_state(u[0]))
    yh = m.simulate(u)[:, 0]
    e = yh + np.mean(y - yh) - y
    return 100 * np.max(np.abs(e)) / np.ptp(y)


def tracking(model, plant, u_train, y_train):
    """Max / RMS tracking error (% FSR) after the first cycle of a 1 Hz triangle, 80 % of range."""
    lo, hi = np.min(y_train), np.max(y_train)
    span = hi - lo
    ref = lo + span * (0.5 + 0.4 * triangle(1.0, 3, 1e-3))
    m = model.with_state(model.consistent_state(u_train[0]))
    if isinstance(model, PreisachModel):
        comp = PreisachCompensator(m)
    else:
        comp = Compensator(m)
    drive = comp.run(ref)[:, 0]  # the model keeps the identification record's offset
    y = plant(np.r_[u_train[0], drive])[1:]  # the actuator starts where the model does
    e = (y - ref)[1000:]
    return 100 * np.max(np.abs(e)) / span, 100 * np.sqrt(np.mean(e**2)) / span


def compare(lines, name, plant, scale=1.0, levels=(20,)):
    recs = []
    for k in KEYS:
        e = EXPERIMENTS[k](seed=0)
        u = e.u[:, 0] * scale
        recs.append((u, e.y[:, 0] if plant is None else plant(u)))
    u0, y0 = recs[0]
    estimators = [("modified PI, 20 operators", PIIdentifier("modified-pi", n_operators=20))]
    estimators += [(f"Preisach, {n} levels", PreisachIdentifier(n_levels=n)) for n in levels]
    for label, est in estimators:
        t = time.perf_counter()
        fit = est.fit((u0, y0))
        dt = time.perf_counter() - t
        errs = [max_err(fit.model, u, y) for u, y in recs]
        row = f"| {name} | {label} | {dt:.2f} | " + " | ".join(f"{x:.3f}" for x in errs)
        if plant is not None:
            tmax, trms = tracking(fit.model, plant, u0, y0)
            row += f" | {tmax:.2f} / {trms:.2f}"
        else:
            row += " | -"
        lines.append(row + " |")


def speed(lines):
    """Simulation time of a fitted 20-level Preisach model and a 20-operator classical PI."""
    u = EXPERIMENTS["decaying-triangle"](seed=0).u[:, 0]
    rng = np.random.default_rng(0)
    walk = np.cumsum(rng.standard_normal(10**5)) * 5.0
    walk = 450 - np.abs((walk + 450) % 1800 - 900)  # reflected into +-450 V
    y = EXPERIMENTS["decaying-triangle"](seed=0).y[:, 0]
    pre = PreisachIdentifier(n_levels=20).fit((u, y)).model
    pi = PIIdentifier("pi", n_operators=20).fit((u, y)).model
    lines.append("\n| input | samples | Preisach 20 levels [CPU ns/sample] | PI 20 operators [CPU ns/sample] | ratio |")
    lines.append("|---|---|---|---|---|")
    for label, x in (("decaying triangle", u), ("reflected random walk", walk)):
        times = {"p": [], "pi": []}
        for mod in (pre, pi):
            mod.simulate(x[:100])
        for _ in range(15):  # alternating pairs: the machine is shared
            for key, mod in (("p", pre), ("pi", pi)):
                t = time.thread_time()  # CPU time: the machine is shared
                mod.simulate(x)
                times[key].append(time.thread_time() - t)
        tp, tq = (np.median(times[k]) / x.size * 1e9 for k in ("p", "pi"))
        ratios = np.median(np.array(times["p"]) / np.array(times["pi"]))
        lines.append(f"| {label} | {x.size} | {tp:.1f} | {tq:.1f} | {ratios:.2f} |")


def main():
    lines = [
        "| actuator | model | fit [s] | max error % ident. | triangle 1 Hz | decaying sine | tracking max / RMS % FSR |"
    ]
    lines.append("|---|---|---|---|---|---|---|")
    compare(lines, "piezo_actuator", None, levels=(20,))
    compare(lines, "mild preisach", Mild(), scale=Mild.scale, levels=(10, 15, 20))
    compare(lines, "skewed preisach", skewed_plant(), levels=(10, 15, 20))
    speed(lines)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
