"""
A Preisach model of a piezo driven by a 150 V sine
==================================================

A discrete Preisach model (uniform-density cells on a triangular threshold grid, weights by
non-negative least squares with a smoothness penalty) identified on ten seconds of a measured
150 V, 1 Hz sine record (samples 35000-45000, as Chandra et al. fit it) and checked on the
record's first seconds. One sine determines few cells (the summary says how many the
smoothness prior filled). The weight map is the discrete Preisach density: where on the
(up-switching, down-switching) threshold plane the actuator's hysteresis sits.

The record lives in ``shared/data/piezo_smarthysteresis``; without it this example uses the
reference piezo actuator of the letter.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.data.datasets import load_smarthysteresis, shared_data_dir
from stageid.hysteresis import PreisachIdentifier, max_error_percent, rms_error_percent
from stageid.plants import plant_module

folder = shared_data_dir()
path = folder / "piezo_smarthysteresis" / "hysteresis_v_150_1hz.csv" if folder else None
if path is not None and path.exists():
    rec = load_smarthysteresis(path)
    u, y = rec.u[:, 0], rec.y[:, 0]
    train, test = slice(35000, 45000), slice(17000, 35000)
else:
    print("smarthysteresis record absent: using the reference piezo actuator")
    rec = plant_module("piezo-actuator").EXPERIMENTS["decaying-sine"](seed=0)
    u, y = rec.u[:, 0], rec.y[:, 0]
    train, test = slice(0, len(u) // 2), slice(len(u) // 2, len(u))

fit = PreisachIdentifier(n_levels=20).fit([(u[train], y[train])])
model = fit.model
print(fit.summary().splitlines()[0])


def best_start(model, u, y):
    """The model's output from the best of the three standard starting memories, own offset."""
    starts = [model.consistent_state(u[0], kind) for kind in ("zero", "ascending", "descending")]
    runs = [model.with_state(state).simulate(u)[:, 0] for state in starts]
    runs = [r + np.mean(y - r) for r in runs]
    return min(runs, key=lambda r: np.mean((y - r) ** 2))


y_test = best_start(model, u[test], y[test])
print(
    f"held-out: max {max_error_percent(y[test], y_test):.2f} %, "
    f"RMS {rms_error_percent(y[test], y_test):.2f} % of the range"
)

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
ax1.plot(u[test], y[test], color="0.6", lw=0.8, label="measured (held out)")
ax1.plot(u[test], y_test, "C1", lw=0.8, label="Preisach, 20 levels")
ax1.set_xlabel("voltage [V]")
ax1.set_ylabel("displacement [um]")
ax1.grid(True, alpha=0.3)
ax1.legend(fontsize=8)
W = model.weight_matrix()  # W[i, j]: up-switching cell i, down-switching cell j (i >= j)
weights = np.ma.masked_where(np.triu(np.ones_like(W, dtype=bool), 1), W)
image = ax2.imshow(weights, origin="lower", cmap="viridis")
ax2.set_xlabel("down-switching threshold cell j")
ax2.set_ylabel("up-switching threshold cell i")
ax2.set_title("cell weights [um per cell]")
fig.colorbar(image, ax=ax2)
plt.show()
