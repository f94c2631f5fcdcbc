"""The statistics of eq. 9 (Cao & Chen 2013, section 2.1): what every later step is computed from.

=============================  ==============================================================
module                         what it holds
=============================  ==============================================================
:mod:`.hankel_toeplitz`        the simplified Hankel-Toeplitz model, its normal equations
                               (``hankel_toeplitz_statistics``), the ``theta`` split (eq. 16)
:mod:`.correlations`           lag correlations, and the window Gram matrix of eq. 9 from them
                               (FFT)
:mod:`.window_covariance`      ``WindowLags``: the lag statistics a fit keeps, and the
                               covariance of the eq. 9 response under overlapping windows
:mod:`.theta_response`         the eq. 9 model's frequency response (and its posterior spread,
                               ``ThetaSpread``: theta with its covariance factors)
:mod:`.chunked_statistics`     the same statistics of a record larger than memory, chunk by
                               chunk
=============================  ==============================================================
"""
