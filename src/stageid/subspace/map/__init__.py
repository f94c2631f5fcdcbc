"""MAP online estimation of the eq. 9 parameters (Cao & Chen 2013, section 2.3, eq. 16-18).

=====================  ===================================================================
module                 what it holds
=====================  ===================================================================
:mod:`.posterior`      ``Prior``, ``Posterior`` (matrix normal), ``map_posterior``,
                       ``batch_posterior``; ``method`` -> prior (``METHODS``)
:mod:`.recursion`      eq. 17-18 sample by sample (``recursive_map``) and its numpy twin
:mod:`.kernels`        the compiled (numba) kernels of that recursion
=====================  ===================================================================
"""
