"""Frequency-response measurements: nonparametric FRF estimation and identification from FRF data.

========================  =================================================================
module                    what it holds
========================  =================================================================
:mod:`.frd`               :class:`FrequencyResponse` (the FRF object), its CSV/NPZ table format
:mod:`.welch`             Welch H1 with pooled cross spectra, multiple coherence, std of H
:mod:`.lpm`               local polynomial method (Pintelon & Schoukens), noise from residuals
:mod:`.lpm_kernels`       compiled LPM line solves (moments, complex Cholesky), edge lines
:mod:`.lpm_lanes`         the same for interior lines, 16 at a time with 4-wide vectors
:mod:`.periodic`          averaging over periods of periodic excitation, noise from the scatter
:mod:`.identification`    :class:`FRDIdentification`: subspace + weighted output-error fit
:mod:`.fit_uncertainty`   covariance of that fit from the data's std, ``FRDResult.response_uncertainty``
:mod:`.plotting`          Bode figure with a +-2 std band and a coherence panel
========================  =================================================================
"""

from .frd import FrequencyResponse, frd_columns, read_frd
from .identification import FRDIdentification, FRDResult
from .lpm import lpm_frf
from .periodic import periodic_frf
from .welch import cross_spectra, default_segment, welch_frf

__all__ = [
    "FrequencyResponse",
    "read_frd",
    "frd_columns",
    "welch_frf",
    "cross_spectra",
    "default_segment",
    "lpm_frf",
    "periodic_frf",
    "FRDIdentification",
    "FRDResult",
]
