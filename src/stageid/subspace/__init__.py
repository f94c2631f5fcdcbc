"""Open-loop MIMO state-space identification: the Hankel-Toeplitz model with recursive MAP
estimation of Cao & Chen (2013), "State space system identification of 3-DOF piezo-actuator-
driven stages with unknown configuration", Actuators 2, 1-18.

Modules follow the paper's sections:

=======================  ===================================================================
``hankel_toeplitz``      2.1 Simplified Hankel-Toeplitz model: regression eq. 9, its normal
                         equations from lag correlations, the model's frequency response
``map_estimator``        2.3 MAP online estimation: prior, posterior, eq. 17-18 recursion
``realization``          2.1-2.2 H0 (eq. 10), H_i (eq. 12), H(0)/H(1) (eq. 14), Lemma 1
                         (eq. 15), frequency-domain realisation over the excited band
``selection``            3.2 choice of p and of the order by held-out prediction error
``estimator``            2.4 the whole method: ``HankelMAP(...).fit(data)`` -> result,
                         per-channel stacking (eq. 19-22), ``result.update(new_data)``
=======================  ===================================================================

``HankelMAP``            the estimator (configure, fit, get a frozen ``HankelMAPResult``)
``HankelMAPResult``      model, posterior, diagnostics, uncertainty bands, ``update``
``Prior``, ``Posterior`` matrix-normal prior/posterior of ``theta = [Gamma Phi D_p]``
``recursive_map``        the sample-by-sample eq. 17-18 (compiled)
"""

from .estimator import ChannelFit, HankelMAP, HankelMAPResult
from .map_estimator import Posterior, Prior, batch_posterior, recursive_map
from .realization import era, frequency_realization, markov_from_theta

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
