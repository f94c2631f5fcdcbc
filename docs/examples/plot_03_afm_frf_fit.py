"""
Fitting a model to a measured FRF: the AFM piezo stage
======================================================

A frequency response measured on an AFM piezo stage (302 lines, 1 Hz to 12 kHz, control
voltage to stage displacement). :class:`~stageid.frf.FRDIdentification` fits a discrete model
(Ts = 40 us) by a frequency-domain subspace start and a weighted output-error refinement, here
of order 16 up to 2 kHz, the band where the stage's first resonances lie.

The record lives in ``shared/data/afm_piezo_stage_frf``; without it this example fits the
P-558 reference stage's ``Z -> z`` response instead.
"""

import numpy as np
import scipy.io

from stageid.data.datasets import shared_data_dir
from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.plants import plant_module

folder = shared_data_dir()
path = folder / "afm_piezo_stage_frf" / "FRF_data_current_stage2.mat" if folder else None
if path is not None and path.exists():
    frf = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)["modelFit"].frf
    data = FrequencyResponse(np.asarray(frf.freqs_Hz), np.asarray(frf.G_uz2stage), inputs=("uz",), outputs=("stage",))
    fit = FRDIdentification(order=16, sample_time=4e-5, band=(1.0, 2000.0))
    unit = "stage / uz"
else:
    print("AFM record absent: fitting the P-558 reference stage instead")
    g = plant_module("p558").model()
    freqs = np.logspace(0, 2.3, 200)
    data = FrequencyResponse(freqs, g.frequency_response(freqs)[:, :1, :1], inputs=("Z",), outputs=("z",))
    fit = FRDIdentification(order=7, sample_time=g.dt)
    unit = "um/um"

result = fit.fit(data)
print(f"order {result.order}, largest error {result.max_error:.3g} (relative to the peak)")
fig = data.plot(model=result.model)
fig.axes[0].set_ylabel(f"|G| [{unit}]")
fig.suptitle("measured FRF and fitted model")
# stageid draws on plain matplotlib Figure objects (no pyplot): fig.savefig("figure.png") saves one
