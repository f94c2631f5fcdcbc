"""stageid: identification and compensation of precision positioning stages.

Sub-packages, one capability each:

==============  =====================================================================
``data``        the :class:`~stageid.data.Experiment` container, readers, preprocessing
``signals``     excitation signals (chirps, PRBS, multisines, hysteresis staircases)
``models``      LTI models (state space, transfer matrix), the ``stageid.lti/1`` format
``subspace``    Hankel-Toeplitz regression, recursive MAP, ERA realisation (Cao & Chen)
``closedloop``  prediction-error methods, plant deduction, order reduction (Shakir & Kim)
``hysteresis``  play / coupled-play operators, PI and modified PI models, inverses
``validation``  fit metrics and residual tests
``plants``      the reference stages of the papers
``cli``         the ``stageid`` command (the only place that prints or exits)
==============  =====================================================================
"""

from ._errors import *  # noqa: F403 - every error and warning class is public at the top level
from ._errors import __all__ as _error_names
from ._moved import install_moved_paths
from .runtime import numba_cache

install_moved_paths()  # old module paths of moved modules still import (see _moved.MOVED)
numba_cache.configure()  # before any kernel is defined: a read-only install must still run

__version__ = "0.1.0"

__all__ = [*_error_names, "__version__"]
