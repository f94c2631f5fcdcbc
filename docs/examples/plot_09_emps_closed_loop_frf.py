"""
A measured closed loop: the EMPS positioning system
===================================================

The electro-mechanical positioning system (EMPS) benchmark was measured under a known PD-type
position controller. Welch estimates of the closed-loop responses from the reference ``qg`` to
the position ``qm`` and to the controller output ``vir`` show what such a record can tell: the
closed loop ``T`` stays close to one over the excited band, so ``1 - T``, from which the indirect
route deduces the plant, is small and dominated by model error: that route fails on this record, while a physical closed-loop
output-error fit recovers the published mass and friction (``studies/closed_loop/RESULTS.md``,
section 3).

The records live in ``shared/data/emps``; without them this example uses a simulated maglev
closed loop.
"""

import matplotlib.pyplot as plt
import numpy as np

from stageid.data import decimate
from stageid.data.datasets import load_emps, shared_data_dir
from stageid.frf import welch_frf
from stageid.plants import plant_module

folder = shared_data_dir()
path = folder / "emps" / "DATA_EMPS.mat" if folder else None
if path is not None and path.exists():
    # the smooth reference holds no power above ~50 Hz: decimate to 10 ms before estimating
    record = decimate(load_emps(path).experiment(["qg"], ["qm", "vir"]), 10)
    units = ("m/m", "V/m")
else:
    print("EMPS records absent: using a simulated maglev closed loop")
    maglev = plant_module("maglev")
    record = maglev.simulate_chirp("x").experiment(["r_x"], ["x", "Fx"])
    units = ("m/m", "N/m")

frf = welch_frf(record, segment=512)
print(f"{record.n_samples} samples, dt = {record.dt} s, {frf.n_freqs} lines of {frf.freqs[1]:.3f} Hz")
low = (frf.freqs > 0) & (frf.freqs < 2.0)
gap = np.abs(1 - frf.response[low, 0, 0])
print(f"|1 - T| below 2 Hz: median {np.median(gap):.2e}, largest {gap.max():.2e}")

fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True, layout="constrained")
f = frf.freqs[1:]
for k, ax in enumerate(axes):
    ax.loglog(f, np.abs(frf.response[1:, k, 0]), "C0", lw=1)
    band = 2 * frf.std[1:, k, 0]
    magnitude = np.abs(frf.response[1:, k, 0])
    # the band's lower edge is clipped at a tenth of the magnitude: a log axis has no zero
    ax.fill_between(
        f, np.maximum(magnitude - band, magnitude / 10), magnitude + band, color="C0", alpha=0.25, label="+-2 std"
    )
    ax.set_ylabel(f"|{frf.outputs[k]} / {frf.inputs[0]}| [{units[k]}]")
    ax.grid(True, which="both", alpha=0.3)
axes[0].legend(fontsize=8)
axes[0].set_title("closed-loop frequency responses from the reference")
axes[1].set_xlabel("frequency [Hz]")
plt.show()
