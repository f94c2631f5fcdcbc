"""Validation: fit metrics shared by every identification method.

==============================  ===========================================================
``fit_percent``                 normalised fit (MATLAB ``compare``) per output channel
``nrmse``                       RMS error over the measured range per channel
``rms_error``                   RMS error per channel
``relative_response_error``     max frequency-response error relative to the true gain
``whiteness_test``              residual whiteness: Ljung-Box chi-square over lags 1..25
``independence_test``           residual-input independence: chi-square over lags 0..25
``residual_tests``              both tests on every output
``validate_model``              simulate a model on records and test it (``stageid validate``)
``edge_errors``                 an error concentrated at a record's start or end
==============================  ===========================================================

Modules:

==============================  ===========================================================
``metrics``                     fit %, NRMSE, RMS and response errors
``correlation_tests``           the whiteness and independence tests (Ljung, sec. 16.6)
``residuals``                   a model's residual tests on records, and their JSON form
``edges``                       a record's start-up or end transient, and the trim for it
``initial_state``               the initial state that best explains a record
``order_choice``                how ``order="auto"`` picks an order; the poor-model warning
==============================  ===========================================================
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
