"""Immutable MIMO state-space models; the class lives in :mod:`stageid.models.lti` with the transfer matrix.

Kept so ``from stageid.models.statespace import StateSpaceModel`` goes on working.
"""

from .lti import StateSpaceModel

__all__ = ["StateSpaceModel"]
