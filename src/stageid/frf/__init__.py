"""Frequency-response measurements: nonparametric FRF estimation and identification from FRF data.

========================  =================================================================
module                    what it holds
========================  =================================================================
:mod:`.estimate`          :class:`FRFResult`: what the three estimators below return
:mod:`.welch`             :class:`WelchFRF`: H1 with pooled cross spectra, multiple
                          coherence, std of H
:mod:`.welch_chunked`     those spectra summed chunk by chunk (records larger than memory)
:mod:`.lpm`               :class:`LocalPolynomialFRF` (Pintelon & Schoukens), noise from
                          the residuals
:mod:`.lpm_kernels`       compiled LPM line solves (moments, complex Cholesky), edge lines
:mod:`.lpm_lanes`         the same for interior lines, 16 at a time with 4-wide vectors
:mod:`.periodic`          :class:`PeriodicFRF`: averaging over periods, noise from the scatter
:mod:`.bla`               best linear approximation over random-phase realisations: noise and
                          total (noise + nonlinear) variance, odd/even detection-line levels
:mod:`.bla_result`        :class:`BLAResult`, the detection-line levels
:mod:`.periods`           the periods of a periodic record and its transient ones
:mod:`.bla_lpm`           transient removal of periodic records by a local polynomial (robust LPM)
:mod:`.bla_figure`        the BLA's classic figure: BLA magnitude, noise and total distortion level
:mod:`.identification`    :class:`FRDIdentification`: subspace + weighted output-error fit
:mod:`.fit_search`        that fit at its optimum: several starts, refinement to convergence
:mod:`.fit_selection`     its order and input delay chosen on held-out frequencies
:mod:`.fit_weights`       its per-frequency weights, column errors and large-error warning
:mod:`.vector_fitting`    common poles by iterated relocation (Gustavsen & Semlyen), a start
:mod:`.mode_exchange`     weakest pole pair moved to a residual peak, out of local minima
:mod:`.fit_uncertainty`   covariance of that fit from the data's std, ``FRDResult.response_uncertainty``
========================  =================================================================

:class:`FrequencyResponse`, ``read_frd`` and ``frd_columns`` live in
:mod:`stageid.models.frequency_response` (a model object that every package's results return);
they are re-exported here, and ``stageid.frf.frd`` still imports as that module.  The FRF's
Bode figure (``FrequencyResponse.plot``) is :mod:`stageid.plots.frf`, drawn by the one
Bode figure of :mod:`stageid.plots.bode`.
"""

from ..runtime.lazy import lazy_names

# Names load on first use (PEP 562): the LPM's numba kernels must not load into the start-up
# of every command that only reads or writes a response (tests/test_import_cost.py).
_WHERE = {
    "FrequencyResponse": "..models.frequency_response",
    "read_frd": "..models.frequency_response",
    "frd_columns": "..models.frequency_response",
    "FRFResult": ".estimate",
    "WelchFRF": ".welch",
    "welch_frf": ".welch",
    "cross_spectra": ".welch",
    "default_segment": ".welch",
    "LocalPolynomialFRF": ".lpm",
    "lpm_frf": ".lpm",
    "PeriodicFRF": ".periodic",
    "periodic_frf": ".periodic",
    "bla_frf": ".bla",
    "BLAAccumulator": ".bla",
    "BLAResult": ".bla_result",
    "FRDIdentification": ".identification",
    "FRDResult": ".identification",
}

__all__ = list(_WHERE)


__getattr__, __dir__ = lazy_names(__name__, _WHERE)
