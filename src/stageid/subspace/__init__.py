"""Open-loop MIMO state-space identification: the Hankel-Toeplitz model with recursive MAP
estimation of Cao & Chen (2013), "State space system identification of 3-DOF piezo-actuator-
driven stages with unknown configuration", Actuators 2, 1-18.

Sub-packages and modules follow the paper's sections; each step of :meth:`HankelMAP.fit` is one
named function:

=======================  ===================================================================
``statistics``           2.1 eq. 9: ``hankel_toeplitz`` (the model, its normal equations,
                         ``theta`` split of eq. 16), ``correlations`` (window Gram matrix from
                         lag correlations), ``window_covariance`` (the lags a fit keeps),
                         ``theta_response`` (the eq. 9 model's frequency response and its
                         posterior spread, ``ThetaSpread``),
                         ``chunked_statistics`` (records larger than memory)
``map``                  2.3 MAP online estimation, eq. 16-18: ``prior`` (eq. 17's prior,
                         ``METHODS``), ``posterior`` (the posterior, batch and update),
                         ``recursion`` (sample by sample), ``kernels`` (compiled)
``realisation``          2.1-2.2 eq. 10-15: ``era`` (H0, H_i, Lemma 1, ``realize`` with its
                         routes), ``frequency_domain`` (the frequency route), ``route``
                         (what a route is given), ``refinement``, ``weighting``,
                         ``output_error`` (the realised model refined on the records)
``selection``            3.2 choice of p and of the order by held-out prediction error;
                         ``split`` (training / held-out statistics), ``nested_horizons``,
                         ``chunked_order``
``uncertainty``          the posterior carried through the realisation to the realised
                         model (delta method or draws); ``grid_placement``,
                         ``realisation_bias``
``channels``             2.4 per-input records (eq. 19), stacking (eq. 20-22,
                         ``stack_channel_models``)
``records``              mean removal, unit-RMS scaling, excited band of the records
``sources``              where the statistics come from: a record source answers what the
                         fit asks of the data; ``RecordArrays`` (records in memory)
``chunked_source``       ``ChunkedSource``: one record larger than memory, chunk by chunk,
                         here or on a Dask cluster (``fit_chunked``)
``estimator``            the whole method: ``HankelMAP(...).fit(data)`` -> result
``channel_fit``          one input group's steps in order, whatever the source: memory
                         check, split and horizon, eq. 9, eq. 16-18, order, eq. 10-15
``result``               ``HankelMAPResult``: model, posterior, diagnostics, ``summary()``,
                         bands, ``update(new_data)``
=======================  ===================================================================

The flat module paths of earlier versions (``stageid.subspace.hankel_toeplitz``,
``stageid.subspace.map_estimator``, ``stageid.subspace.chunked_fit``, ...) still import, as the modules at their new places
(:mod:`stageid._moved`).

``HankelMAP``            the estimator (configure, fit, get a frozen ``HankelMAPResult``)
``HankelMAPResult``      model, posterior, diagnostics, uncertainty bands, ``update``
``Prior``, ``Posterior`` matrix-normal prior/posterior of ``theta = [Gamma Phi D_p]``
``recursive_map``        the sample-by-sample eq. 17-18 (compiled)
"""

from .estimator import HankelMAP
from .map.posterior import Posterior, Prior, batch_posterior
from .map.recursion import recursive_map
from .realisation.era import era, markov_from_theta
from .realisation.frequency_domain import frequency_realization
from .result import ChannelFit, HankelMAPResult

__all__ = [
    "HankelMAP",
    "HankelMAPResult",
    "ChannelFit",
    "Prior",
    "Posterior",
    "batch_posterior",
    "recursive_map",
    "era",
    "frequency_realization",
    "markov_from_theta",
]
