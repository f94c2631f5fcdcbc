"""
A 2x2 mechatronic system: the DaISy CD player arm
=================================================

The CD player arm of the DaISy database (two actuator forces, two tracking outputs, 2048
samples, coloured inputs, sample time not given and so taken as 1). Hankel-MAP identifies a
MIMO model on the first three quarters and is judged on the last quarter by MATLAB's
``compare`` fit, ``100 (1 - |y - y_model| / |y - mean(y)|)``.

The set lives in ``shared/data/daisy``; without it this example uses a record of the P-558
reference stage.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.data import split
from stageid.data.datasets import load_daisy, shared_data_dir
from stageid.plants import plant_module
from stageid.subspace import HankelMAP
from stageid.validation import fit_percent

folder = shared_data_dir()
if folder is not None and (folder / "daisy" / "CD_player_arm.dat").exists():
    record = load_daisy("cd_player_arm")
    time_unit, y_unit = "samples", "(as recorded)"
else:
    print("DaISy set absent: using the P-558 reference stage")
    record = plant_module("p558").EXPERIMENTS["band-limited"](seed=0)
    time_unit, y_unit = "s", "[um, urad]"

train, test = split(record, 0.75)
result = HankelMAP().fit(train)
model = result.model
print(result.summary().splitlines()[0])
# simulate from rest over the whole record, so that the test quarter starts from a warm state
y_model = model.simulate(record.u - train.u.mean(axis=0)) + train.y.mean(axis=0)
tail = slice(train.n_samples, None)
fits = fit_percent(record.y[tail], y_model[tail])
for name, fit in zip(record.output_names, fits):
    print(f"{name}: fit {fit:.1f} % on the held-out quarter")

t = np.arange(record.n_samples) * record.dt
fig, axes = plt.subplots(record.n_outputs, 1, figsize=(9, 2.4 * record.n_outputs), sharex=True, layout="constrained")
for k, ax in enumerate(np.atleast_1d(axes)):
    ax.plot(t[tail], record.y[tail, k], color="0.5", lw=0.8, label="measured")
    ax.plot(t[tail], y_model[tail, k], "C1", lw=0.8, label=f"model, fit {fits[k]:.1f} %")
    ax.set_ylabel(f"{record.output_names[k]} {y_unit}")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(True, alpha=0.3)
np.atleast_1d(axes)[-1].set_xlabel(f"time [{time_unit}]")
plt.show()
