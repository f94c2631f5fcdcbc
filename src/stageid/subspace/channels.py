"""Per-input-channel identification and stacking, Cao & Chen (2013) section 2.4 (eq. 19-22).

The stage is linear, so each input channel ``u_i`` can be identified on its own from the
records in which only that input moves (a one-input model, eq. 19), and the sub-models
stacked into the MIMO model: ``A = diag(A_i)``, ``B = diag(B_i)``, ``C = [C_1 ... C_m]``,
``D = [D_1 ... D_m]`` (eq. 20-22).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from ..models.statespace import StateSpaceModel

__all__ = ["channel_groups", "stack_channel_models"]

Records = list[tuple[np.ndarray, np.ndarray]]


def channel_groups(records: Records, names: Sequence[str], per_channel: bool) -> list[tuple[list[int], Records]]:
    """The (input columns, records) of every sub-model: all inputs and all records for a direct
    MIMO fit, or (eq. 19) one group per input with the records in which only it moves.

    Raises
    ------
    DataError
        When ``per_channel`` and some input has no record in which only it moves.
    """
    m = len(names)
    if not per_channel:
        return [(list(range(m)), records)]
    groups = []
    for j in range(m):
        sel = []
        for u, y in records:
            moving = [np.ptp(u[:, i]) > 0 for i in range(m)]
            if moving[j] and sum(moving) == 1:
                sel.append((u[:, [j]], y))
        if not sel:
            raise DataError(
                f"per-channel identification needs, for input '{names[j]}', a record in "
                f"which only that input moves; got none."
            )
        groups.append(([j], sel))
    return groups


def stack_channel_models(
    models: Sequence[StateSpaceModel], dt: float, inputs: Sequence[str], outputs: Sequence[str]
) -> StateSpaceModel:
    """Eq. 19-22: the one-input models ``(A_i, B_i, C_i, D_i)`` of eq. 19 stacked into the MIMO model
    ``A = diag(A_i)``, ``B = diag(B_i)``, ``C = [C_1 ... C_m]``, ``D = [D_1 ... D_m]`` (eq. 20-22;
    the outputs add up, eq. 21).  One model is returned as it is, with the channel names."""
    if len(models) == 1:
        return models[0].with_names(inputs, outputs)
    import scipy.linalg as sla

    A = sla.block_diag(*[g.A for g in models])
    B = sla.block_diag(*[g.B for g in models])
    C = np.hstack([g.C for g in models])
    D = np.hstack([g.D for g in models])
    return StateSpaceModel(A, B, C, D, dt, tuple(inputs), tuple(outputs))
