"""Exceptions and warnings shared by every part of stageid.

Every error raised on purpose derives from :class:`StageIdError` and also from the
built-in exception it refines, so ``except ValueError`` keeps working for callers
that do not know stageid.  Messages say what was expected and what came, e.g.
"`B` must have shape (15, 3); got (5, 3)."
"""

from __future__ import annotations

__all__ = [
    "StageIdError",
    "DataError",
    "NoSampleTimeError",
    "ModelError",
    "ModelFormatError",
    "SignalError",
    "IdentificationError",
    "ParameterError",
    "ResourceError",
    "ClusterError",
    "StageIdWarning",
    "ExcitationWarning",
    "FitWarning",
    "StabilityWarning",
]


class StageIdError(Exception):
    """Base class of every error stageid raises on purpose."""


class DataError(StageIdError, ValueError):
    """Measured data are unusable: NaN/inf, ragged columns, bad time axis, unknown names."""


class NoSampleTimeError(DataError):
    """A record has no time column and no sample time was given (a caller may supply one)."""


class ModelError(StageIdError, ValueError):
    """A model is inconsistent or an operation on it is undefined (e.g. no real logarithm)."""


class ModelFormatError(ModelError):
    """A model file (``stageid.lti/1`` or a hysteresis JSON) is malformed."""


class SignalError(StageIdError, ValueError):
    """An excitation signal was asked for with impossible or out-of-limit parameters."""


class IdentificationError(StageIdError, RuntimeError):
    """Identification could not produce a model (singular problem, no convergence, ...)."""


class ParameterError(StageIdError, ValueError):
    """A setting is invalid: an estimator's hyper-parameter or a function's option.

    Every estimator raises it for a bad setting, from its ``fit`` (where the settings are
    checked, see :class:`stageid.base.Estimator`); the message names the setting, what was
    expected and what came.
    """


class ResourceError(StageIdError, MemoryError):
    """A request would need more memory (or work) than this machine can give; nothing was done.

    Raised before the work starts (see :mod:`stageid.runtime.resources`), with what the request would
    need and what is available.
    """


class ClusterError(StageIdError, ConnectionError):
    """A Dask scheduler could not be reached, or a cluster could not be started."""


class StageIdWarning(UserWarning):
    """Base class of every warning stageid issues; filter on it to silence them all."""


class ExcitationWarning(StageIdWarning):
    """The data are not persistently exciting for the requested model."""


class StabilityWarning(StageIdWarning):
    """An identified or requested model is unstable where stability was expected."""


class FitWarning(StageIdWarning):
    """An identified model leaves a large error on the data it was fitted to."""
