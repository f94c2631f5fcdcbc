"""Play operator (eq. 1-2) and coupled-play operator (eq. 3) of the modified-PI letter.

Play operator
=============
For a threshold ``r >= 0`` and a sampled input ``x(k)`` the play operator is (eq. 1)::

    z(k) = max(x(k) - r, min(x(k) + r, z(k-1)))

with the initial consistency condition (eq. 2) ``z(0) = max(x(0) - r, min(x(0) + r, z0))``
(``z0`` usually 0).  The letter's eq. 1 is missing the second argument of ``min`` in the OCR;
the form above is the standard one (Krasnosel'skii & Pokrovskii).

Coupled-play (CP) operator: the consistent reading of eq. 3
==========================================================
Eq. 3 arrived through OCR as five cases.  Read literally it has three typos and one defect:

1. case 3 prints ``x(k) - ra`` but its own condition is ``x(k) + ra <= z(k-1)``: the output is
   ``x(k) + ra`` (a descending branch lies *above* the input, like ``x + r`` of the play);
2. case 4 likewise prints ``x(k) - rb`` under ``x(k) + rb <= z(k-1)``: output ``x(k) + rb``;
3. the "others" case prints ``x(k-1)``; holding the *input* would make the output jump to the
   input on every small reversal.  It must hold the previous output ``z(k-1)``, as the play
   does (and as the initial condition ``z0(k-1)`` in the operator's signature says);
4. the switches of eq. 3 sit where the branch outputs cross zero: the ascending branch
   ``x - rc`` (for ``x < rc``) reaches 0 at ``x = rc`` where the ``x - r`` branch takes over,
   and the descending branch ``x + rb`` (for ``x > -rb``) reaches 0 at ``x = -rb`` where
   ``x + ra`` takes over.  Evaluated literally, sample by sample, the case conditions make
   the result depend on the sampling: an input that jumps from below ``rc`` to above it in one
   sample leaves the output stuck below zero, while the same path sampled finely does not.
   That is not rate independent.  The consistent reading is the continuous-time operator the
   figure draws, evaluated exactly at the samples: a play operator whose ascending and
   descending *boundary curves* are::

       gamma_up(x)   = max(x - r, min(x - rc, 0))    # x - rc below zero, flat 0, x - r above
       gamma_down(x) = min(x + ra, max(x + rb, 0))   # x + rb above zero, flat 0, x + ra below

       z(k) = max(gamma_up(x(k)), min(gamma_down(x(k)), z(k-1)))

   For ``rc <= r`` and ``rb <= ra`` this agrees with eq. 3 (with 1-3 corrected) whenever the
   input moves by less than the flat part per sample, and stays exact for any sampling.  The
   thresholds are therefore required to satisfy ``0 <= rc <= r`` and ``0 <= rb <= ra``
   (otherwise the literal branches would jump; the continuous operator would simply ignore
   the inactive threshold).

Above zero output the CP operator is a play with ascending threshold ``r`` and descending
threshold ``rb``; below zero it is a play with ascending threshold ``rc`` and descending ``ra``;
the two are coupled by a flat stretch at ``z = 0``.  Different widths above and below zero make
the loops asymmetric, the flat stretches make them flatter (concave) near the origin; with
``r = rc = ra = rb`` the CP operator *is* the play operator.

Properties (tested in ``tests/test_hysteresis_operators.py``): rate independence (inserting
samples on a monotone stretch changes nothing), the wiping-out property, asymmetry, the
initial consistency condition ``z(0) = max(gamma_up(x(0)), min(gamma_down(x(0)), z0))`` with
the letter's ``x0 = z0 = 0``, and the reduction to the play operator.

State
=====
:class:`OperatorState` holds the last input ``x`` and every operator's output ``z``; each
simulation returns the final state, so a model resumes exactly where a record ended.

References
----------
Modified Prandtl-Ishlinskii hysteresis modelling letter (``shared/papers``), eq. 1-4.
M. A. Krasnosel'skii and A. V. Pokrovskii, *Systems with Hysteresis*, Springer 1989.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..._errors import ModelError
from .common import as_input

__all__ = [
    "OperatorState",
    "play",
    "coupled_play",
    "gamma_up",
    "gamma_down",
    "play_reference",
    "coupled_play_reference",
]


@dataclass(frozen=True, eq=False)
class OperatorState:
    """Memory of a bank of (coupled-)play operators: the last input and every output.

    Parameters
    ----------
    x : float
        The input at the last sample (the letter's ``x0(k-1)``).
    z : array_like of shape (n_operators,)
        The operator outputs at the last sample (the letter's ``z0(k-1)``).

    Examples
    --------
    >>> from stageid.hysteresis.models.operators import OperatorState
    >>> s = OperatorState(0.0, [0.0, 0.0])
    >>> s.z.shape
    (2,)
    """

    x: float
    z: np.ndarray

    def __post_init__(self) -> None:
        z = np.array(self.z, dtype=float, copy=True).reshape(-1)
        x = float(self.x)
        if not np.isfinite(x) or not np.all(np.isfinite(z)):
            raise ModelError(
                f"operator state must be finite; got x={x} and z with {int(np.sum(~np.isfinite(z)))} non-finite values."
            )
        z.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "z", z)

    @classmethod
    def zeros(cls, n_operators: int) -> OperatorState:
        """The letter's initial state ``x0 = 0``, ``z0 = 0``."""
        return cls(0.0, np.zeros(n_operators))


def gamma_up(x: np.ndarray | float, r: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """Ascending boundary ``max(x - r, min(x - rc, 0))`` of the CP operator (see module notes)."""
    return np.maximum(x - r, np.minimum(x - rc, 0.0))


def gamma_down(x: np.ndarray | float, ra: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """Descending boundary ``min(x + ra, max(x + rb, 0))`` of the CP operator (see module notes)."""
    return np.minimum(x + ra, np.maximum(x + rb, 0.0))


def _thresholds(name: str, value: object, n: int | None = None) -> np.ndarray:
    arr = np.array(value, dtype=float, copy=True).reshape(-1)
    if n is not None and arr.size != n:
        raise ModelError(f"`{name}` must have {n} entries (one per operator); got {arr.size}.")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ModelError(f"`{name}` thresholds must be finite and >= 0; got {arr.tolist()}.")
    return arr


def check_cp_thresholds(r: object, rc: object, ra: object, rb: object) -> tuple[np.ndarray, ...]:
    """Validate CP thresholds: 1-D, equal length, finite, ``0 <= rc <= r``, ``0 <= rb <= ra``."""
    r_ = _thresholds("r", r)
    rc_ = _thresholds("rc", rc, r_.size)
    ra_ = _thresholds("ra", ra, r_.size)
    rb_ = _thresholds("rb", rb, r_.size)
    tol = 1e-12 * (1.0 + np.abs(r_))
    if np.any(rc_ > r_ + tol):
        i = int(np.argmax(rc_ - r_))
        raise ModelError(
            f"CP thresholds need rc <= r (else eq. 3 jumps); operator {i} has rc={rc_[i]:g} > r={r_[i]:g}."
        )
    if np.any(rb_ > ra_ + 1e-12 * (1.0 + np.abs(ra_))):
        i = int(np.argmax(rb_ - ra_))
        raise ModelError(
            f"CP thresholds need rb <= ra (else eq. 3 jumps); operator {i} has rb={rb_[i]:g} > ra={ra_[i]:g}."
        )
    return r_, np.minimum(rc_, r_), ra_, np.minimum(rb_, ra_)


def _bank_reference(
    x: np.ndarray, m: int, z0: np.ndarray, update: Callable[[float, int, float], float]
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``m`` operators sample by sample: ``z_i <- update(x_k, i, z_i)``; outputs and final outputs."""
    out = np.empty((x.shape[0], m))
    z = [float(v) for v in z0]
    for k in range(x.shape[0]):
        xk = float(x[k])
        for i in range(m):
            z[i] = update(xk, i, z[i])
            out[k, i] = z[i]
    return out, np.array(z)


def play_reference(x: np.ndarray, r: np.ndarray, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plain-Python play bank, eq. 1-2, sample by sample (the reference the kernels are tested against).

    Returns the outputs of shape (n_samples, n_operators) and the final outputs.
    """
    return _bank_reference(x, r.shape[0], z0, lambda xk, i, zi: max(xk - r[i], min(xk + r[i], zi)))


def coupled_play_reference(
    x: np.ndarray, r: np.ndarray, rc: np.ndarray, ra: np.ndarray, rb: np.ndarray, z0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Plain-Python CP bank, eq. 3 in the consistent reading of the module notes."""

    def update(xk: float, i: int, zi: float) -> float:
        up = max(xk - r[i], min(xk - rc[i], 0.0))
        down = min(xk + ra[i], max(xk + rb[i], 0.0))
        return max(up, min(down, zi))

    return _bank_reference(x, r.shape[0], z0, update)


def play(x: object, r: object, state: OperatorState | None = None) -> tuple[np.ndarray, OperatorState]:
    """Outputs of a bank of play operators (eq. 1-2) for one input record.

    Parameters
    ----------
    x : array_like of shape (n_samples,) or (n_samples, 1)
        Input samples.
    r : array_like of shape (n_operators,)
        Thresholds, >= 0.
    state : OperatorState, optional
        Starting state; default the letter's ``x0 = z0 = 0``.

    Returns
    -------
    z : ndarray of shape (n_samples, n_operators)
        Operator outputs.
    state : OperatorState
        The final state (resume the next record from it).

    Raises
    ------
    ModelError
        If thresholds are negative or shapes disagree.

    Examples
    --------
    >>> from stageid.hysteresis.models.operators import play
    >>> z, s = play([0.0, 2.0, 1.0, -2.0], [1.0])
    >>> z[:, 0].tolist()
    [0.0, 1.0, 1.0, -1.0]
    """
    from .. import kernels

    xx = np.ascontiguousarray(as_input(x, "x"))
    rr = _thresholds("r", r)
    st = state if state is not None else OperatorState.zeros(rr.size)
    if st.z.size != rr.size:
        raise ModelError(f"state must hold {rr.size} operator outputs; got {st.z.size}.")
    z, zf = kernels.play_bank(xx, rr, np.array(st.z))
    return z, OperatorState(float(xx[-1]) if xx.size else st.x, zf)


def coupled_play(
    x: object, r: object, rc: object, ra: object, rb: object, state: OperatorState | None = None
) -> tuple[np.ndarray, OperatorState]:
    """Outputs of a bank of coupled-play operators (eq. 3, consistent reading) for one record.

    Parameters
    ----------
    x : array_like of shape (n_samples,) or (n_samples, 1)
        Input samples.
    r, rc, ra, rb : array_like of shape (n_operators,)
        Thresholds with ``0 <= rc <= r`` and ``0 <= rb <= ra``: ascending above / below zero
        output (``r`` / ``rc``), descending below / above zero output (``ra`` / ``rb``).
    state : OperatorState, optional
        Starting state; default ``x0 = z0 = 0`` (the letter's initial consistency condition).

    Returns
    -------
    z : ndarray of shape (n_samples, n_operators)
    state : OperatorState

    Raises
    ------
    ModelError
        If the thresholds violate the ordering or shapes disagree.

    Examples
    --------
    >>> from stageid.hysteresis.models.operators import coupled_play
    >>> z, _ = coupled_play([0.0, 3.0, 0.0, -3.0, 0.0], [1.0], [0.5], [2.0], [1.0])
    >>> z[:, 0].tolist()
    [0.0, 2.0, 1.0, -1.0, -0.5]
    """
    from .. import kernels

    xx = np.ascontiguousarray(as_input(x, "x"))
    r_, rc_, ra_, rb_ = check_cp_thresholds(r, rc, ra, rb)
    st = state if state is not None else OperatorState.zeros(r_.size)
    if st.z.size != r_.size:
        raise ModelError(f"state must hold {r_.size} operator outputs; got {st.z.size}.")
    z, zf = kernels.cp_bank(xx, r_, rc_, ra_, rb_, np.array(st.z))
    return z, OperatorState(float(xx[-1]) if xx.size else st.x, zf)
