"""MAP online estimation of the eq. 9 parameters (Cao & Chen 2013, section 2.3, eq. 16-18).

=====================  ===================================================================
module                 what it holds
=====================  ===================================================================
:mod:`.prior`          ``Prior`` (matrix normal, eq. 17), the default and least-squares
                       priors; ``method`` -> prior (``METHODS``)
:mod:`.posterior`      ``Posterior`` (matrix normal), ``map_posterior``,
                       ``batch_posterior`` (the prior's names re-exported)
:mod:`.recursion`      eq. 17-18 sample by sample (``recursive_map``) and its numpy twin
:mod:`.kernels`        the compiled (numba) kernels of that recursion
=====================  ===================================================================
"""
