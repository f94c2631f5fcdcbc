"""
Modified Prandtl-Ishlinskii model of a measured piezo actuator
==============================================================

Identify the letter's modified PI model (20 coupled-play operators) on a measured
first-order-reversal-curve staircase (20 cycles/s, +-90 V, dSPACE, 10 kHz) and check it on a
record it has not seen: a 5 Hz triangle driven by a feedforward, with minor loops. The
validation record's output offset and starting memory are fitted with the model fixed, as
MATLAB's ``compare`` estimates initial states.

The records live in ``shared/data/piezo_dspace_preisach``; without them this example uses the
reference piezo actuator of the letter.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.data.datasets import load_dspace_piezo, shared_data_dir
from stageid.hysteresis import PIIdentifier, align_record, max_error_percent, rms_error_percent
from stageid.plants import plant_module


def trimmed(exp):
    """Drop the idle second before the drive moves, and the last samples of the capture."""
    u, y = exp.u[:, 0], exp.y[:, 0]
    start = max(0, int(np.flatnonzero(np.abs(np.diff(u)) > 1e-9)[0]) - int(0.1 / exp.dt))
    return u[start:-10], y[start:-10]


folder = shared_data_dir()
folder = folder / "piezo_dspace_preisach" if folder else None
if folder is not None and folder.is_dir():
    ident = trimmed(load_dspace_piezo(folder / "20_hz_no_lp.mat"))
    valid = trimmed(load_dspace_piezo(folder / "tri50_1.mat"))
    names = ("20 Hz FORC staircase", "5 Hz triangle (tri50_1)")
else:
    print("dSPACE records absent: using the reference piezo actuator")
    actuator = plant_module("piezo-actuator")
    ident = tuple(a[:, 0] for a in (lambda e: (e.u, e.y))(actuator.EXPERIMENTS["decaying-triangle"](seed=0)))
    valid = tuple(a[:, 0] for a in (lambda e: (e.u, e.y))(actuator.EXPERIMENTS["triangle-1hz"](seed=1)))
    names = ("decaying triangle", "1 Hz triangle")

fit = PIIdentifier("modified-pi", n_operators=20, input_warp=False).fit([ident])  # the letter's model
print(fit.summary().splitlines()[0])
_, y_valid = align_record(fit.model, *valid)
print(f"identification: max {fit.max_error_percent[0]:.2f} %, RMS {fit.rms_error_percent[0]:.2f} % of the range")
print(
    f"validation:     max {max_error_percent(valid[1], y_valid):.2f} %, "
    f"RMS {rms_error_percent(valid[1], y_valid):.2f} % of the range"
)

fig, axes = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
y_ident = align_record(fit.model, *ident)[1]
for ax, (u, y), y_model, name in zip(axes, (ident, valid), (y_ident, y_valid), names):
    ax.plot(u, y, color="0.6", lw=0.8, label="measured")
    ax.plot(u, y_model, "C1", lw=0.8, label="modified PI")
    ax.set_title(name)
    ax.set_xlabel("drive voltage [V]")
    ax.set_ylabel("displacement [um]")
    ax.grid(True, alpha=0.3)
axes[0].legend(fontsize=8)
plt.show()
