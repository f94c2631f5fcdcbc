"""
Inverse feedforward: classical and modified PI compensators
===========================================================

The letter's Fig. 9 scheme on its reference piezo actuator: identify a classical and a modified
PI model (20 operators) on a decaying triangle, invert each into a streaming
:class:`~stageid.hysteresis.Compensator`, and drive the actuator with the compensator's output
to follow a 1 Hz, 3 um triangle. Without compensation (the drive scaled by the open-loop gain)
the actuator's hysteresis shows as a loop of output against reference.
"""

import matplotlib.pyplot as plt

from stageid.hysteresis import Compensator, PIIdentifier, hysteresis_percent, tracking_error_percent
from stageid.plants import plant_module
from stageid.signals import triangle

actuator_module = plant_module("piezo-actuator")
actuator = actuator_module.model()
ident = actuator_module.EXPERIMENTS["decaying-triangle"](seed=0)
dt = ident.dt

y_ref = triangle(1.0, 3.0, dt, amplitude=1.5) + 0.5  # um
drives = {"no compensation": y_ref / actuator_module.open_loop_gain(actuator)}
for kind, label in (("pi", "classical-PI inverse"), ("modified-pi", "modified-PI inverse")):
    fit = PIIdentifier(kind, n_operators=20, input_warp=False).fit(ident)
    drives[label] = Compensator(fit.model, limits=(-500.0, 500.0)).run(y_ref)[:, 0]

fig, ax = plt.subplots(figsize=(6, 5), layout="constrained")
for label, drive in drives.items():
    y = actuator.simulate(drive)[:, 0]
    print(
        f"{label:22s} tracking error {tracking_error_percent(y_ref, y):5.2f} % FSR, "
        f"hysteresis {hysteresis_percent(y_ref, y):5.2f} %"
    )
    ax.plot(y_ref, y, lw=1, label=label)
ax.set_xlabel("reference displacement [um]")
ax.set_ylabel("actuator displacement [um]")
ax.set_title("output against reference: a line means no hysteresis")
ax.grid(True, alpha=0.3)
ax.legend(fontsize=8)
plt.show()
