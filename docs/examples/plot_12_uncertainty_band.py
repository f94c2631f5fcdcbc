"""
How far each frequency can be trusted: uncertainty bands
========================================================

Every identification result gives the standard deviation of its model's frequency response,
``std = sqrt(E|G_est - G|^2)``, from the estimator's own statistics (for Hankel-MAP the
covariance of the eq. 9 estimate carried through the realisation). With a short, noisy record
of the P-558 stage (order 7, the paper's order of this channel) the band is wide where the chirp
put little power and narrow where it put much. The band holds the estimate's variance, not its
bias: the printed share of frequencies where the true response lies within +-2 std shows how far
short of the nominal 95 % that falls here (``studies/uncertainty/RESULTS.md`` measures the
calibration on many stages).
"""

import numpy as np

from stageid.data import Experiment
from stageid.plants import plant_module
from stageid.subspace import HankelMAP

p558 = plant_module("p558")
rec = p558.EXPERIMENTS["chirp-z"](seed=0)
rng = np.random.default_rng(3)
noisy = Experiment(rec.u[:, :1], rec.y[:, :1] + 0.02 * rng.standard_normal((rec.n_samples, 1)), rec.dt, ("Z",), ("z",))
result = HankelMAP(order=7).fit(noisy)

freqs = np.geomspace(1.0, 100.0, 200)  # Hz
band = result.response_uncertainty(freqs)
true = p558.model().frequency_response(freqs)[:, :1, :1]
inside = np.abs(true - band.response)[:, 0, 0] <= 2 * band.std[:, 0, 0]
print(f"true response within +-2 std at {100 * inside.mean():.0f} % of {freqs.size} frequencies")

fig = band.plot()
ax = fig.axes[0]
ax.loglog(freqs, np.abs(true[:, 0, 0]), "k--", lw=1, label="true")
ax.set_ylabel("|G| Z -> z [um/um]")
ax.legend(fontsize=8)
fig.suptitle("Hankel-MAP model of a noisy record, +-2 std band")
# stageid draws on plain matplotlib Figure objects (no pyplot): fig.savefig("figure.png") saves one
