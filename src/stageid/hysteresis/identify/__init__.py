"""Identification of PI, modified-PI and Preisach models from input/output records.

The letter's identification, one step per module (``PIIdentifier.fit`` calls them in order):

=============================  ==============================================================
module                         what it holds
=============================  ==============================================================
:mod:`.pi`                     ``PIIdentifier``: steps 1-5 in order (step 1, equally spaced
                               thresholds, is a line there)
:mod:`.weights`                step 2: operator weights by constrained least squares
                               (invertibility bounds)
:mod:`.threshold_search`       step 3: CP thresholds of the modified PI (grid, Nelder-Mead,
                               settling of several starts)
:mod:`.threshold_polish`       step 3: Gauss-Newton on the projected residual (a start to the
                               bottom of its valley)
:mod:`.records`                the records read once (``Records``), step 4: starting
                               states, per-record errors, ``align_record``
:mod:`.weight_uncertainty`     covariance of the weights (block-robust least squares)
:mod:`.preisach`               ``PreisachIdentifier``: NNLS cell weights with a smoothness
                               penalty
:mod:`.result`                 ``HysteresisResult``, ``PreisachResult``: the model, per-record
                               errors, diagnostics
=============================  ==============================================================
"""
