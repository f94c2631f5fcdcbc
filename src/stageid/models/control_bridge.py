"""Conversions to and from python-control objects, on arrays (``control`` is imported on first use)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .conversions import dt_from_control

__all__ = ["to_control_ss", "from_control_ss", "to_control_tf", "from_control_tf", "is_control_ss"]


def to_control_ss(A, B, C, D, dt: float | None, inputs: Sequence[str], outputs: Sequence[str]) -> Any:
    """A ``control.StateSpace`` (``dt = 0`` for continuous time) with the channel labels."""
    import control

    return control.ss(A, B, C, D, 0 if dt is None else dt, inputs=list(inputs), outputs=list(outputs))


def from_control_ss(sys: Any) -> tuple:
    """``(A, B, C, D, dt, inputs, outputs)`` of a ``control.StateSpace`` (or anything ``control.ss`` accepts)."""
    import control

    if not isinstance(sys, control.StateSpace):
        sys = control.ss(sys)
    dt = dt_from_control(sys.dt)
    return (
        np.asarray(sys.A),
        np.asarray(sys.B),
        np.asarray(sys.C),
        np.asarray(sys.D),
        dt,
        tuple(sys.input_labels),
        tuple(sys.output_labels),
    )


def is_control_ss(sys: Any) -> bool:
    """True for a ``control.StateSpace``."""
    import control

    return isinstance(sys, control.StateSpace)


def to_control_tf(num, den, dt: float | None, inputs: Sequence[str], outputs: Sequence[str]) -> Any:
    """A ``control.TransferFunction`` with the same coefficients and labels."""
    import control

    return control.tf(
        [[list(e) for e in row] for row in num],
        [[list(e) for e in row] for row in den],
        0 if dt is None else dt,
        inputs=list(inputs),
        outputs=list(outputs),
    )


def from_control_tf(sys: Any) -> tuple:
    """``(num, den, dt, inputs, outputs)`` of a ``control.TransferFunction`` (or anything ``control.tf`` accepts)."""
    import control

    if not isinstance(sys, control.TransferFunction):
        sys = control.tf(sys)
    num = [[np.asarray(sys.num_list[i][j], dtype=float) for j in range(sys.ninputs)] for i in range(sys.noutputs)]
    den = [[np.asarray(sys.den_list[i][j], dtype=float) for j in range(sys.ninputs)] for i in range(sys.noutputs)]
    return num, den, dt_from_control(sys.dt), tuple(sys.input_labels), tuple(sys.output_labels)
