"""
Closed-loop identification of the unstable maglev stage
=======================================================

The maglev stage of Shakir & Kim is open-loop unstable (three right-half-plane poles at 54.6,
82.2 and 86.7 rad/s), so it can only be measured in closed loop. One chirp per reference, the
known stabilising controller, and :class:`~stageid.closedloop.ClosedLoopIdentification`: PEM
fits of the closed-loop transfers, the plant deduced from them and the controller, cancelled
pole-zero pairs removed and each entry reduced over 20-300 Hz. The unstable poles come out of
the deduction.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.closedloop import ClosedLoopIdentification
from stageid.plants import plant_module

maglev = plant_module("maglev")
outs = list(maglev.OUTPUTS)
refs = [f"r_{o}" for o in outs]
records = [
    maglev.simulate_chirp(axis, seed=k).experiment(refs, outs, name=f"chirp-{axis}") for k, axis in enumerate(outs)
]
result = ClosedLoopIdentification(maglev.controller(), band=(20.0, 300.0)).fit(records)

true = maglev.model()
print(
    "unstable poles [rad/s]: identified",
    np.sort(np.asarray(result.plant_unstable_poles).real).round(1),
    "paper (54.6, 82.2, 86.7)",
)
f = np.geomspace(20.0, 300.0, 300)
G_true, G_id = true.frequency_response(f), result.model.frequency_response(f)
rel = np.max(np.abs(G_id - G_true) / np.abs(G_true), axis=0)
print("largest error on the diagonal, 20-300 Hz [%]:", np.round(100 * np.diag(rel), 2), "(paper: below 1 %)")

units = ("m/N", "m/N", "rad/(N m)")
fig, axes = plt.subplots(1, 3, figsize=(10, 3.2), layout="constrained")
for k, ax in enumerate(axes):
    ax.loglog(f, np.abs(G_true[:, k, k]), "k", lw=2, label="true plant")
    ax.loglog(f, np.abs(G_id[:, k, k]), "C1--", label="identified in closed loop")
    ax.set_title(f"{maglev.INPUTS[k]} -> {outs[k]}")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"|G| [{units[k]}]")
    ax.grid(True, which="both", alpha=0.3)
axes[0].legend(fontsize=8)
plt.show()
