"""
The P-558 piezo stage: the reference model of Cao & Chen
========================================================

The 3-DOF piezo stage (inputs ``Z`` [um], ``Rx``, ``Ry`` [urad]) identified in the Hankel-MAP
paper, eq. 23-25, as stageid ships it: a 15-state discrete model at Ts = 2 ms. Its Bode
magnitude shows the near-unit diagonal and the small cross-coupling that a MIMO identification
must get right.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.plants import plant_module

p558 = plant_module("p558")
g = p558.model()
print(f"{g.n_states} states, inputs {g.inputs}, outputs {g.outputs}, dt = {g.dt} s")
print("poles |z| max:", np.abs(g.poles()).max().round(4))

freqs = np.logspace(0, np.log10(200), 300)  # Hz, up to 80 % of Nyquist
response = g.frequency_response(freqs)  # (n_freqs, n_outputs, n_inputs)
units_in, units_out = p558.INPUT_UNITS, p558.OUTPUT_UNITS

fig, axes = plt.subplots(3, 3, figsize=(9, 7), sharex=True, layout="constrained")
for i in range(3):
    for j in range(3):
        ax = axes[i, j]
        ax.loglog(freqs, np.abs(response[:, i, j]))
        ax.set_title(f"{g.inputs[j]} -> {g.outputs[i]}", fontsize=9)
        ax.set_ylabel(f"|G| [{units_out[i]}/{units_in[j]}]", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
for ax in axes[-1]:
    ax.set_xlabel("frequency [Hz]")
fig.suptitle("P-558 reference model: Bode magnitude")
plt.show()
