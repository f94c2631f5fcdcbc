"""Open-loop MIMO state-space identification: the Hankel-Toeplitz model with recursive MAP
estimation of Cao & Chen (2013), "State space system identification of 3-DOF piezo-actuator-
driven stages with unknown configuration", Actuators 2, 1-18.

Modules follow the paper's sections; each step of :meth:`HankelMAP.fit` is one named function:

=======================  ===================================================================
``hankel_toeplitz``      2.1 Simplified Hankel-Toeplitz model: eq. 9 statistics
                         (``hankel_toeplitz_statistics``), ``theta`` split (eq. 16)
``theta_response``       2.1 the eq. 9 model's frequency response (and its posterior spread)
``correlations``         2.1 the window Gram matrix of eq. 9 from lag correlations (FFT)
``map_estimator``        2.3 MAP online estimation: prior, posterior, eq. 17-18
                         (``map_posterior``); ``method`` -> prior (``METHODS``)
``recursion``            2.3 eq. 17-18 sample by sample (``recursive_map``) and its numpy twin
``map_kernels``          2.3 the compiled (numba) kernels of that recursion
``unroll``               writes out the kernels' short constant-count loops before compiling
``realization``          2.1-2.2 H0 (eq. 10), H_i (eq. 12), H(0)/H(1) (eq. 14), Lemma 1
                         (eq. 15, ``era``); ``realize`` with ``realization`` -> route
                         (``REALIZATIONS``)
``frequency_domain``     the frequency route: the eq. 9 response over the excited band
                         realised (frequency counterpart of Lemma 1), two starts
``refinement``           output-error refinement of a realisation on that response
``weighting``            noise weighting of the outputs in the realisation and selection
``selection``            3.2 choice of p and of the order by held-out prediction error
``channels``             2.4 per-input records (eq. 19), stacking (eq. 20-22,
                         ``stack_channel_models``)
``records``              mean removal, unit-RMS scaling, excited band of the records
``estimator``            the whole method: ``HankelMAP(...).fit(data)`` -> result
``result``               ``HankelMAPResult``: model, posterior, bands, ``update(new_data)``
``uncertainty``          the posterior carried through the realisation to the realised model
                         (``HankelMAPResult.response_uncertainty``: delta method or draws)
=======================  ===================================================================

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
