"""
A measured maglev record without a trusted controller model
===========================================================

Three 3-axis magnetometers [mT] and the PWM commands to the x and y solenoid pairs of a
magnetic-levitation stage under PD control, about 2700 samples/s. The controller is not known
for certain, so the closed-loop route cannot deduce the plant. What can be said: the Welch
estimate from the PWM commands to the field, with its coherence, is a *closed-loop* estimate -
the commands react to the measurement noise, so where the coherence is high the estimate is
the ratio of the loop's sensitivities, not the open-loop plant, and it is biased where the
noise drives the commands.

The record lives in ``shared/data/maglev_closedloop``; without it this example uses a simulated
closed-loop maglev record, where the same estimate can be set beside the true plant.
"""

import matplotlib.pyplot as plt
import numpy as np
import scipy.io

from stageid.data import Experiment
from stageid.data.datasets import shared_data_dir
from stageid.frf import welch_frf
from stageid.plants import plant_module

folder = shared_data_dir()
path = folder / "maglev_closedloop" / "PD_data_with_input.mat" if folder else None
if path is not None and path.exists():
    content = scipy.io.loadmat(path)
    start = int(np.flatnonzero(np.any(content["u"] != 0, axis=1))[0])  # the first samples are idle
    u = content["u"][start:].astype(float)  # PWM counts, saturated at +-255
    y = content["rawMeasurements1"][start:, :2].astype(float)  # bx, by of the first sensor [mT]
    record = Experiment(u - u.mean(axis=0), y - y.mean(axis=0), 1 / 2700, ("pwm_x", "pwm_y"), ("bx", "by"))
    units = "mT/count"
    saturated = float(np.mean(np.abs(u) >= 255))
else:
    print("measured maglev record absent: using a simulated closed loop")
    maglev = plant_module("maglev")
    record = maglev.simulate_chirp("x").experiment(["Fx", "Fy"], ["x", "y"])
    units = "m/N"
    saturated = 0.0

print(f"{record.n_samples} samples, dt = {record.dt:.3g} s")
print(f"commands at their limit in {100 * saturated:.1f} % of the samples")
frf = welch_frf(record, segment=1024)
good = frf.coherence[:, 0] > 0.9
print(f"multiple coherence of {frf.outputs[0]} above 0.9 at {100 * good.mean():.0f} % of {frf.n_freqs} lines")

fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True, layout="constrained")
f = frf.freqs[1:]
for i in range(2):
    ax1.loglog(f, np.abs(frf.response[1:, i, i]), lw=1, label=f"{frf.inputs[i]} -> {frf.outputs[i]}")
    ax2.semilogx(f, frf.coherence[1:, i], lw=1, label=frf.outputs[i])
ax1.set_ylabel(f"|H| [{units}]")
ax1.set_title("closed-loop Welch estimate: not the open-loop plant")
ax1.legend(fontsize=8)
ax1.grid(True, which="both", alpha=0.3)
ax2.set_ylabel("multiple coherence [-]")
ax2.set_xlabel("frequency [Hz]")
ax2.set_ylim(0, 1.05)
ax2.legend(fontsize=8)
ax2.grid(True, which="both", alpha=0.3)
plt.show()
