"""
Residual tests: whiteness and independence, as MATLAB's resid
=============================================================

A model explains a record when what it leaves, ``e = y - y_model``, is white and unrelated to
the input. :func:`~stageid.validation.validate_model` simulates a model on a record and runs
both tests per output (Ljung-Box over 25 lags, chi-squared at the 1 % level; the input
prewhitened for the independence test). A stage with two lightly damped modes (120 and 450 Hz),
white sensor noise: the true model leaves only the noise and passes both tests; a model with the
first mode only fails them by orders of magnitude, and the figure shows at which lags.
"""

import numpy as np

from stageid.data import Experiment
from stageid.models import StateSpaceModel, c2d
from stageid.plots.residuals import residual_figure
from stageid.validation import validate_model


def modes(*pairs):
    """Continuous model: a sum of unit-DC-gain second-order modes ``(f_hz, damping, weight)``."""
    A, B, C = [], [], []
    for f, zeta, weight in pairs:
        w = 2 * np.pi * f
        A.append([[0.0, 1.0], [-(w**2), -2 * zeta * w]])
        B.append([[0.0], [w**2]])
        C.append([weight, 0.0])
    n = 2 * len(pairs)
    A_full = np.zeros((n, n))
    for k, block in enumerate(A):
        A_full[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = block
    return StateSpaceModel(A_full, np.vstack(B), [np.concatenate(C)], [[0.0]], dt=None, inputs=["u"], outputs=["y"])


dt = 1e-4  # s
true = c2d(modes((120.0, 0.02, 0.8), (450.0, 0.01, 0.2)), dt)
first_mode_only = c2d(modes((120.0, 0.02, 1.0)), dt)

rng = np.random.default_rng(0)
u = rng.standard_normal((20000, 1))  # V
y = true.simulate(u) + 0.002 * rng.standard_normal((20000, 1))  # um, white sensor noise
record = Experiment(u, y, dt, ("u",), ("y",))

for label, model in (("true model", true), ("first mode only", first_mode_only)):
    out = validate_model(model, [record])["outputs"]["y"]
    print(
        f"{label:16s} fit {out['fit_percent']:6.2f} %   whiteness {'pass' if out['whiteness'].passed else 'FAIL'} "
        f"(chi2 {out['whiteness'].statistic:8.1f}, limit {out['whiteness'].threshold:.1f})   "
        f"independence {'pass' if out['independence']['u'].passed else 'FAIL'}"
    )

out = validate_model(first_mode_only, [record])["outputs"]["y"]
fig = residual_figure("y [um], first mode only", out["whiteness"], out["independence"])
fig.axes[-1].set_xlabel("lag [samples of 0.1 ms]")
# stageid draws on plain matplotlib Figure objects (no pyplot): fig.savefig("figure.png") saves one
