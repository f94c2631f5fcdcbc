"""Validation: fit metrics shared by every identification method.

==============================  ===========================================================
``fit_percent``                 normalised fit (MATLAB ``compare``) per output channel
``nrmse``                       RMS error over the measured range per channel
``rms_error``                   RMS error per channel
``relative_response_error``     max frequency-response error relative to the true gain
``whiteness_test``              residual whiteness: Ljung-Box chi-square over lags 1..25
``independence_test``           residual-input independence: chi-square over lags 0..25
``residual_tests``              both tests on every output (:mod:`.residuals`)
``validate_model``              simulate a model on records and test it (``stageid validate``)
``edge_errors``                 an error concentrated at a record's start or end (:mod:`.edges`)
==============================  ===========================================================

:mod:`.order_choice` holds the rule by which every ``order="auto"`` picks an order from its
validation errors, and the one text of the warning for a poor model.
"""

from .edges import EdgeError, edge_errors
from .metrics import fit_percent, nrmse, relative_response_error, rms_error
from .residuals import independence_test, residual_tests, validate_model, whiteness_test

__all__ = [
    "fit_percent",
    "nrmse",
    "rms_error",
    "relative_response_error",
    "whiteness_test",
    "independence_test",
    "residual_tests",
    "validate_model",
    "EdgeError",
    "edge_errors",
]
