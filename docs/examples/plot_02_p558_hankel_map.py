"""
Hankel-MAP on the P-558 stage: identified versus true response
==============================================================

Three 10 s chirps, one per input, as in section 3.2 of Cao & Chen: :class:`~stageid.subspace.HankelMAP`
chooses the horizon and the order by held-out prediction error and realises one MIMO model.
The identified and true models are compared by their frequency responses, which do not depend
on the state basis.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.plants import plant_module
from stageid.subspace import HankelMAP

p558 = plant_module("p558")
records = [p558.EXPERIMENTS[f"chirp-{c}"](seed=0) for c in ("z", "rx", "ry")]
result = HankelMAP().fit(records)
model = result.model
print(result.summary().splitlines()[0])

freqs = np.logspace(0, 2, 200)  # Hz: the chirps' band
true = p558.model().frequency_response(freqs)
ident = model.frequency_response(freqs)
error = np.abs(ident - true).max(axis=0) / np.abs(true).max(axis=0)
print("largest error per entry, relative to the entry's peak [%]:")
print(np.array2string(100 * error, precision=2))

fig, axes = plt.subplots(1, 3, figsize=(10, 3.2), layout="constrained")
for k, ax in enumerate(axes):
    ax.loglog(freqs, np.abs(true[:, k, k]), "k", lw=2, label="true (eq. 23-25)")
    ax.loglog(freqs, np.abs(ident[:, k, k]), "C1--", label=f"Hankel-MAP, {model.n_states} states")
    ax.set_title(f"{model.inputs[k]} -> {model.outputs[k]}")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"|G| [{p558.OUTPUT_UNITS[k]}/{p558.INPUT_UNITS[k]}]")
    ax.grid(True, which="both", alpha=0.3)
axes[0].legend(fontsize=8)
plt.show()
