"""Plant deduction from an identified closed loop and the known controller (eq. 15, 18).

Conventions (Shakir & Kim, Fig. 3 and eq. 15): the controller acts on the tracking error,
``u = M (r - y)``, the plant gives ``y = G u`` (plus output noise).  Then

    y = G M (r - y)   =>   T = (I + G M)^-1 G M          (eq. 15, MIMO form)

and, because ``(I + G M) T = G M`` gives ``T = G M (I - T)``,

    G = T [M (I - T)]^-1 = T (M - M T)^-1                   (eq. 18).

``M (I - T)`` is exactly the closed-loop map from ``r`` to ``u``, so eq. 18 is
``G = T_yr T_ur^-1``.  The SISO special case is ``G = T / (M (1 - T))``.  The OCR'd paper
prints ``q = z^-1``; we read every transfer function as a rational function of ``z`` (with
``q^-1`` the backward shift), the only reading under which eq. 11 and 15 are consistent.

Everything is discrete (the sample time of the data); convert with
:func:`stageid.models.d2c` afterwards.  A two-degree-of-freedom law ``u = M_r r - M y``
is handled by ``reference_filter=M_r``: then ``T = (I + G M)^-1 G M_r`` and
``G = T (M_r - M T)^-1``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg as sla

from .._errors import IdentificationError
from ..models import StateSpaceModel, TransferMatrix
from .controller import (  # the controller's half, re-exported where it was
    as_discrete_controller,
    as_statespace,
    check_controller,
    check_grid,
    discrete_controllers,
    resolved_grid,
)

__all__ = [
    "deduce_response",
    "deduce_plant",
    "deduce_siso",
    "unstable_plant_poles",
    "as_discrete_controller",
    "discrete_controllers",
    "check_grid",
    "resolved_grid",
    "check_controller",
    "check_deduction",
    "plant_response",
    "wide_response",
]


def check_deduction(
    closed_loop: TransferMatrix,
    controller: StateSpaceModel,
    reference_filter: StateSpaceModel | None,
    freqs_hz: np.ndarray,
) -> None:
    """Eq. 18 evaluated on ``freqs_hz`` (poles of ``T`` or the controllers skipped); IdentificationError where singular."""
    with np.errstate(all="ignore"):
        T = closed_loop.frequency_response(freqs_hz)
        M = controller.frequency_response(freqs_hz)
        Mr = M if reference_filter is None else reference_filter.frequency_response(freqs_hz)
    ok = np.all(np.isfinite(T) & np.isfinite(M) & np.isfinite(Mr), axis=(1, 2))
    deduce_response(T[ok], M[ok], Mr[ok], freqs_hz[ok])


def plant_response(
    closed_loop: TransferMatrix | StateSpaceModel,
    controller: StateSpaceModel | TransferMatrix,
    reference_filter: StateSpaceModel | TransferMatrix | None,
    freqs_hz: np.ndarray,
) -> np.ndarray:
    """The full-order deduced plant's response (eq. 18) at ``freqs_hz``, shape (n_freqs, p, p)."""
    return deduce_response(
        closed_loop.frequency_response(freqs_hz),
        controller.frequency_response(freqs_hz),
        None if reference_filter is None else reference_filter.frequency_response(freqs_hz),
        freqs_hz,
    )


def wide_response(T, M, Mr, G_full):
    """The plant's response for the numerator refits of the cancellation: eq. 18 frequency by frequency.

    Where ``M (I - T)`` is singular on the grid (a controller zero on the unit circle) the
    non-minimal realisation's own response is used, as before.
    """

    def response(freqs_hz: np.ndarray) -> np.ndarray:
        try:
            return plant_response(T, M, Mr, freqs_hz)
        except IdentificationError:
            return G_full.frequency_response(freqs_hz)

    return response


def deduce_response(
    T: np.ndarray,
    M: np.ndarray,
    reference_filter: np.ndarray | None = None,
    freqs_hz: Sequence[float] | None = None,
    rcond: float = 1e-6,
) -> np.ndarray:
    """Eq. 18 frequency by frequency: ``G(f) = T(f) [M(f) (I - T(f))]^-1``.

    Parameters
    ----------
    T : ndarray of shape (n_freqs, p, p)
        Closed-loop response from references to outputs.
    M : ndarray of shape (n_freqs, p, p)
        Controller response (error to plant input).
    reference_filter : ndarray of shape (n_freqs, p, p), optional
        ``M_r`` of a two-degree-of-freedom law ``u = M_r r - M y``; default ``M``.
    freqs_hz : sequence of float, optional
        Only used to name the frequency in the error message.
    rcond : float
        ``M (I - T)`` counts as singular where its smallest singular value is below ``rcond``
        times the controller's typical gain (the median over the given frequencies of the
        largest singular value of ``M_r``); a controller zero on the unit circle leaves
        only rounding there, ~1e-8 of that scale.

    Returns
    -------
    ndarray of shape (n_freqs, p, p)

    Raises
    ------
    IdentificationError
        When ``M (I - T)`` is singular at some frequency (the deduction is undefined there).

    Examples
    --------
    >>> import numpy as np
    >>> G, M = np.array([[[2.0 + 1j]]]), np.array([[[0.5]]])
    >>> T = G * M / (1 + G * M)
    >>> np.allclose(deduce_response(T, M), G)
    True
    """
    T = np.asarray(T, dtype=complex)
    M = np.asarray(M, dtype=complex)
    Mr = M if reference_filter is None else np.asarray(reference_filter, dtype=complex)
    if T.ndim != 3 or M.shape != T.shape or Mr.shape != T.shape or T.shape[1] != T.shape[2]:
        raise IdentificationError(
            f"T, M (and M_r) must all have shape (n_freqs, p, p); got {T.shape}, {M.shape} and {Mr.shape}."
        )
    U = Mr - M @ T
    svals = np.linalg.svd(U, compute_uv=False)
    # scale: the controller's typical size (median over the grid of its largest singular value)
    scale = float(np.median(np.linalg.svd(Mr, compute_uv=False)[:, 0])) if svals.size else 1.0
    bad = np.flatnonzero(svals[:, -1] <= rcond * max(scale, 1e-300))
    if bad.size:
        k = int(bad[0])
        where = f"{freqs_hz[k]:.6g} Hz" if freqs_hz is not None else f"frequency index {k}"
        raise IdentificationError(
            f"the plant deduction G = T (M - M T)^-1 is singular at {where}: the smallest singular value of M (I - T) is "
            f"{svals[k, -1]:.3g}, {svals[k, -1] / max(scale, 1e-300):.2g} of the controller's typical gain (controller zero or perfect tracking there)."
        )
    return T @ np.linalg.inv(U)


# ------------------------------------------------------------ state-space algebra
def _inverse(g: StateSpaceModel) -> StateSpaceModel:
    if g.n_inputs != g.n_outputs:
        raise IdentificationError(f"only a square system can be inverted; got {g.n_outputs}x{g.n_inputs}.")
    s = np.linalg.svd(g.D, compute_uv=False)
    if s.size and s[-1] <= 1e-12 * max(s[0], 1e-300):
        raise IdentificationError(
            "the plant deduction needs a biproper M (I - T): the controller's direct feed-through D must be invertible "
            "(a strictly proper controller makes T_ur strictly proper and eq. 18 improper)."
        )
    Di = np.linalg.inv(g.D)
    return StateSpaceModel(g.A - g.B @ Di @ g.C, g.B @ Di, -Di @ g.C, Di, g.dt, g.outputs, g.inputs)


def _sub(a: StateSpaceModel, b: StateSpaceModel) -> StateSpaceModel:
    na, nb = a.n_states, b.n_states
    A = np.block([[a.A, np.zeros((na, nb))], [np.zeros((nb, na)), b.A]])
    return StateSpaceModel(A, np.vstack([a.B, b.B]), np.hstack([a.C, -b.C]), a.D - b.D, a.dt, a.inputs, a.outputs)


def _mul(left: StateSpaceModel, right: StateSpaceModel) -> StateSpaceModel:
    """``left @ right`` (right acts first)."""
    nr, nl = right.n_states, left.n_states
    A = np.block([[right.A, np.zeros((nr, nl))], [left.B @ right.C, left.A]])
    B = np.vstack([right.B, left.B @ right.D])
    C = np.hstack([left.D @ right.C, left.C])
    return StateSpaceModel(A, B, C, left.D @ right.D, right.dt, right.inputs, left.outputs)


def _balanced(g: StateSpaceModel) -> StateSpaceModel:
    """Diagonal similarity that balances ``A`` (same transfer function, far better numerics:
    the deduction mixes controller gains ~1e6 with plant gains ~1e-6)."""
    if g.n_states == 0:
        return g
    A, T = sla.matrix_balance(g.A, permute=False)
    d = np.diag(T)
    return StateSpaceModel(A, g.B / d[:, None], g.C * d[None, :], g.D, g.dt, g.inputs, g.outputs)


def _identity(p: int, dt: float | None) -> StateSpaceModel:
    return StateSpaceModel(np.zeros((0, 0)), np.zeros((0, p)), np.zeros((p, 0)), np.eye(p), dt)


def deduce_plant(
    closed_loop: StateSpaceModel | TransferMatrix,
    controller: StateSpaceModel | TransferMatrix,
    reference_filter: StateSpaceModel | TransferMatrix | None = None,
) -> StateSpaceModel:
    """Eq. 18 as a (non-minimal) discrete state-space model ``G = T [M (I - T)]^-1``.

    Parameters
    ----------
    closed_loop : StateSpaceModel or TransferMatrix
        Identified discrete ``T`` (p references to p outputs).
    controller : StateSpaceModel or TransferMatrix
        Known discrete ``M`` (p errors to p plant inputs), same sample time, biproper.
    reference_filter : optional
        ``M_r`` of a two-degree-of-freedom law ``u = M_r r - M y``.

    Returns
    -------
    StateSpaceModel
        The full-order deduced plant, states ``[x_T; x_M; x_T]``-like; it carries the
        spurious pole-zero pairs of section 3.2.3 (see :mod:`stageid.closedloop.cancellation`).
        Inputs are the controller's output names, outputs the closed loop's.

    Raises
    ------
    IdentificationError
        Wrong dimensions, different sample times, or a controller without invertible
        feed-through.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.models import TransferMatrix, StateSpaceModel, feedback, c2d
    >>> G = c2d(StateSpaceModel([[1.0]], [[1.0]], [[1.0]], [[0.0]]), 0.01)   # unstable 1/(s-1)
    >>> M = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[5.0]], 0.01)
    >>> T = feedback(G, M)
    >>> T = StateSpaceModel(T.A, T.B, T.C[:1], T.D[:1], 0.01)
    >>> Gh = deduce_plant(T, M)
    >>> np.allclose(Gh.frequency_response([1.0, 10.0]), G.frequency_response([1.0, 10.0]))
    True
    """
    T = as_statespace(closed_loop)
    M = as_statespace(controller)
    Mr = M if reference_filter is None else as_statespace(reference_filter)
    p = T.n_outputs
    if T.n_inputs != p:
        raise IdentificationError(
            f"the closed loop must be square (one reference per output); got {p} outputs and {T.n_inputs} references."
        )
    if M.n_inputs != p or M.n_outputs != p or Mr.n_inputs != p or Mr.n_outputs != p:
        raise IdentificationError(
            f"the controller must map the {p} tracking errors to {p} plant inputs; got {M.n_inputs} inputs and {M.n_outputs} outputs."
        )
    if (
        T.dt is None
        or M.dt is None
        or not np.isclose(T.dt, M.dt, rtol=1e-6)
        or (Mr.dt is None or not np.isclose(Mr.dt, T.dt, rtol=1e-6))
    ):
        raise IdentificationError(
            f"closed loop and controller must be discrete with one sample time; got dt={T.dt} and dt={M.dt}."
        )
    Tr = T.with_names(inputs=tuple(f"r{i + 1}" for i in range(p)))
    U = _sub(_mul(Mr, _identity(p, T.dt)), _mul(M, Tr))  # M_r - M T  (r -> u)
    G = _balanced(_mul(Tr, _inverse(U)))
    return G.with_names(inputs=M.outputs, outputs=T.outputs)


def deduce_siso(
    num_t: np.ndarray, den_t: np.ndarray, num_m: np.ndarray, den_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """SISO eq. 18 in polynomials, keeping every factor as the paper's eq. 19-21 do.

    With ``T = B/A`` and ``M = N_M / D_M`` (descending powers of ``z``, equal-length
    padding), ``G = T / (M (1 - T)) = (B A D_M) / (A N_M (A - B))``: the roots of ``A``
    appear on both sides, and those of ``N_M`` and ``D_M`` nearly cancel against roots
    of ``B`` and ``A - B`` — the spurious pairs of section 3.2.3.

    Returns
    -------
    (num, den) : ndarrays, descending powers of ``z``

    Examples
    --------
    >>> num, den = deduce_siso([0.0, 1.0], [1.0, 0.5], [2.0], [1.0])
    >>> np.round(np.roots(den), 6).tolist()   # A = z + 0.5 and A - B = z - 0.5
    [-0.5, 0.5]
    >>> np.round(np.roots(num), 6).tolist()   # A again: the spurious pair at z = -0.5
    [-0.5]
    """
    B = np.atleast_1d(np.asarray(num_t, dtype=float))
    A = np.atleast_1d(np.asarray(den_t, dtype=float))
    n = max(A.size, B.size)
    A = np.concatenate([np.zeros(n - A.size), A])
    B = np.concatenate([np.zeros(n - B.size), B])
    num = np.polymul(np.polymul(B, A), np.asarray(den_m, dtype=float))
    den = np.polymul(np.polymul(A, np.asarray(num_m, dtype=float)), A - B)
    nz = np.flatnonzero(den)
    if nz.size == 0:
        raise IdentificationError("the SISO deduction is singular: M (1 - T) is identically zero.")
    return num, den


def unstable_plant_poles(
    closed_loop: StateSpaceModel | TransferMatrix,
    controller: StateSpaceModel | TransferMatrix,
    reference_filter: StateSpaceModel | TransferMatrix | None = None,
) -> np.ndarray:
    """Discrete unstable poles of the deduced plant: zeros of ``M_r - M T`` outside the unit circle.

    ``(M_r - M T)^-1`` has its poles at the zeros of ``M_r - M T``; with ``M_r = M`` those are
    the zeros of ``M`` and of ``I - T = (I + G M)^-1``, i.e. the poles of ``G`` and ``M``.
    The controller's own unstable zeros (of ``M_r``) are removed from the list.

    Returns
    -------
    ndarray of complex, the ``z``-plane poles with ``|z| > 1``, sorted by modulus.
    """
    T = as_statespace(closed_loop)
    M = as_statespace(controller)
    Mr = M if reference_filter is None else as_statespace(reference_filter)
    p = T.n_outputs
    U = _sub(_mul(Mr, _identity(p, T.dt)), _mul(M, T.with_names(inputs=tuple(f"r{i + 1}" for i in range(p)))))
    Ui = _inverse(U)
    eig = np.linalg.eigvals(Ui.A) if Ui.n_states else np.zeros(0, complex)
    cand = eig[np.abs(eig) > 1.0 + 1e-9]
    # remove zeros of M_r itself that lie outside the unit circle (not plant poles)
    if Mr.n_states:
        Mri = _inverse(Mr)
        mz = np.linalg.eigvals(Mri.A)
        for z in mz[np.abs(mz) > 1.0 + 1e-9]:
            if cand.size:
                k = int(np.argmin(np.abs(cand - z)))
                if abs(cand[k] - z) < 1e-6 * max(1.0, abs(z)):
                    cand = np.delete(cand, k)
    return cand[np.argsort(np.abs(cand))]
