"""Validation: fit metrics shared by every identification method.

==============================  ===========================================================
``fit_percent``                 normalised fit (MATLAB ``compare``) per output channel
``nrmse``                       RMS error over the measured range per channel
``rms_error``                   RMS error per channel
``relative_response_error``     max frequency-response error relative to the true gain
==============================  ===========================================================
"""

from .metrics import fit_percent, nrmse, relative_response_error, rms_error

__all__ = ["fit_percent", "nrmse", "rms_error", "relative_response_error"]
