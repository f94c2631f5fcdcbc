"""Immutable MIMO transfer matrices; the class lives in :mod:`stageid.models.lti` with the state-space model.

Kept so ``from stageid.models.transfer import TransferMatrix`` goes on working.
"""

from .lti import TransferMatrix

__all__ = ["TransferMatrix"]
