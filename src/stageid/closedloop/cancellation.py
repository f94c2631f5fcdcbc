"""Spurious pole-zero pairs of the deduced plant and their cancellation (section 3.2.3).

Eq. 18 divides by ``M (I - T)``; with ``T = B/A`` the roots of ``A`` appear in numerator
and denominator, and the controller's poles and zeros nearly cancel against roots of the
identified ``B`` and ``A - B`` (the factors ``s^2 + 335 s + 1.275e6`` and
``s^2 + 6102 s + 1.109e7`` of eq. 19-21).  Exact pairs cancel to rounding; the others
cancel only up to the identification error, so each cancellation is reported with its
distance ``|s_p - s_z| / max(|s_p|, 1 rad/s)`` in the ``s``-plane (``s = ln(z) / dt``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .._errors import IdentificationError
from ..models import StateSpaceModel, TransferMatrix
from ..models.minimal import controllable_basis

__all__ = ["CancelledPair", "EntryPoleZero", "PlantEntries", "cancel_pairs", "cancel_entries", "z_to_s"]


@dataclass(frozen=True)
class CancelledPair:
    """One removed pole-zero pair of entry ``(output, input)``; ``pole``/``zero`` in rad/s."""

    output: int
    input: int
    pole: complex
    zero: complex
    distance: float


@dataclass(frozen=True, eq=False)
class EntryPoleZero:
    """Poles and zeros (``z``-plane) of one entry before and after cancellation."""

    output: int
    input: int
    poles: np.ndarray
    zeros: np.ndarray
    kept_poles: np.ndarray
    kept_zeros: np.ndarray
    gain: float
    pairs: tuple[CancelledPair, ...]

    def polynomials(self) -> tuple[np.ndarray, np.ndarray]:
        """``(num, den)`` of the cancelled entry, descending powers of ``z``."""
        num = self.gain * np.real(np.poly(self.kept_zeros)) if self.kept_zeros.size else np.array([self.gain])
        den = np.real(np.poly(self.kept_poles)) if self.kept_poles.size else np.array([1.0])
        return num, den


def z_to_s(z: np.ndarray, dt: float) -> np.ndarray:
    """``s = ln(z) / dt`` (principal branch; ``z = 0`` maps to ``-1e12``)."""
    z = np.asarray(z, dtype=complex)
    out = np.full(z.shape, -1e12 + 0j)
    nz = np.abs(z) > 1e-300
    out[nz] = np.log(z[nz]) / dt
    return out


def cancel_pairs(
    poles: np.ndarray,
    zeros: np.ndarray,
    dt: float,
    tol: float = 1e-2,
    output: int = 0,
    input: int = 0,
    unstable_tol: float = 0.25,
) -> tuple[np.ndarray, np.ndarray, tuple[CancelledPair, ...]]:
    """Remove pole-zero pairs closer than ``tol`` (relative, in the ``s``-plane).

    Parameters
    ----------
    poles, zeros : ndarray of complex
        ``z``-plane roots of one SISO entry.
    dt : float
        Sample time in seconds.
    tol : float
        Pairs with ``|s_p - s_z| / max(|s_p|, 1)`` below ``tol`` are cancelled, nearest first.
    unstable_tol : float
        Looser tolerance for a right-half-plane pole facing a right-half-plane zero.  The
        deduction carries every unstable pole of ``G`` into every entry (through
        ``(I - T)^-1``); in an entry that does not have it, it is met by a zero that the
        identification error (largest at low frequency) displaces by a few percent.

    Returns
    -------
    (kept_poles, kept_zeros, pairs)

    Examples
    --------
    >>> import numpy as np
    >>> p, z, pairs = cancel_pairs(np.array([0.9, 0.5]), np.array([0.50001]), dt=1e-3)
    >>> p.tolist(), z.size, len(pairs)
    ([(0.9+0j)], 0, 1)
    """
    P = np.asarray(poles, dtype=complex).reshape(-1)
    Z = np.asarray(zeros, dtype=complex).reshape(-1)
    sp, sz = z_to_s(P, dt), z_to_s(Z, dt)
    # distances once; pairs taken nearest first (smallest d / limit, ties in row-major order), as
    # argmin over the distance matrix with the cancelled rows and columns masked takes them
    d = np.abs(sp[:, None] - sz[None, :]) / np.maximum(np.abs(sp), 1.0)[:, None]
    limit = np.where((sp.real[:, None] > 0) & (sz.real[None, :] > 0), unstable_tol, tol)
    with np.errstate(divide="ignore", invalid="ignore"):  # tol = 0: never cancelled (inf, or 0/0)
        ratio = (d / limit).ravel()
    keep_p, keep_z = np.ones(P.size, bool), np.ones(Z.size, bool)
    pairs: list[CancelledPair] = []
    # only ratios <= 1 can cancel (d < limit); past them every remaining pair has d > limit
    cand = np.flatnonzero(ratio <= 1.0)
    for k in cand[np.argsort(ratio[cand], kind="stable")]:
        i, j = divmod(int(k), Z.size)
        if not (keep_p[i] and keep_z[j]):
            continue
        if d[i, j] >= limit[i, j]:
            break
        pairs.append(CancelledPair(output, input, complex(sp[i]), complex(sz[j]), float(d[i, j])))
        keep_p[i] = keep_z[j] = False
    return P[keep_p], Z[keep_z], tuple(pairs)


def _siso_pz(g: StateSpaceModel) -> tuple[np.ndarray, np.ndarray]:
    if g.n_states == 0:
        return np.zeros(0, complex), np.zeros(0, complex)
    # poles and zeros of the same realisation: ``g.zeros()`` would minimise ``g`` again with its own
    # rank tolerance and may drop a state of a near-cancelling cluster (the controller's repeated
    # slow pole), leaving that pole without its zero
    poles = np.linalg.eigvals(g.A)
    zeros = g.zeros(minimal=False)
    return poles, zeros


def _unit(M: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(M, 2) if M.size else 0.0
    return M / norm if norm > 0 else M


class PlantEntries:
    """The SISO entries of one plant and their minimal realisations.

    The balancing of ``A`` is the same for every entry, and the controllable part (the first
    half of :func:`~stageid.models.minimal.minimal_matrices`) the same for every entry of one
    input: both are computed once and shared (the numbers are those of the entry-by-entry
    route), and so are the poles where that part is already minimal (:meth:`poles_zeros`).
    """

    def __init__(self, plant: StateSpaceModel, minimal_tol: float | None) -> None:
        self.plant = plant
        A = plant.A
        self.tdiag = None
        if A.shape[0]:
            A, T = sla.matrix_balance(A, permute=False, separate=False)
            self.tdiag = T.diagonal()
        self.A = A
        self.tol = minimal_tol if minimal_tol is not None else 1e-8 * max(1.0, np.linalg.norm(A, 2))
        self._controllable: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._poles: dict[int, np.ndarray] = {}

    def entry(self, i: int, j: int) -> StateSpaceModel:
        b = self.plant.B[:, [j]]
        c = self.plant.C[[i]]
        if self.tdiag is not None:
            b = b / self.tdiag[:, None]
            c = c * self.tdiag[None, :]
        nb = max(np.linalg.norm(b), 1e-300)
        nc = max(np.linalg.norm(c), 1e-300)
        d = self.plant.D[[i]][:, [j]] / (nb * nc)
        return StateSpaceModel(self.A, b / nb, c / nc, d, self.plant.dt)

    def _parts(self, i: int, j: int):
        """``(g, Ac, Bc, Cc, Qo)``: the entry, its controllable part and that part's observable basis."""
        g = self.entry(i, j)
        if j not in self._controllable:
            Qc = controllable_basis(g.A, _unit(g.B), self.tol)
            self._controllable[j] = (Qc, Qc.T @ g.A @ Qc, Qc.T @ g.B)
        Qc, Ac, Bc = self._controllable[j]
        Cc = g.C @ Qc
        return g, Ac, Bc, Cc, controllable_basis(Ac.T, _unit(Cc.T), self.tol)

    def minimal(self, i: int, j: int) -> StateSpaceModel:
        """``minimal_realization(entry(i, j), tol)``."""
        if self.plant.n_states == 0:
            return self.entry(i, j)
        g, Ac, Bc, Cc, Qo = self._parts(i, j)
        return StateSpaceModel(Qo.T @ Ac @ Qo, Qo.T @ Bc, Cc @ Qo, g.D.copy(), g.dt)

    def poles_zeros(self, i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Poles and zeros (``z``-plane) of one minimal realisation of entry ``(i, j)``.

        Where the observability step keeps every controllable state (every maglev entry), the
        controllable part ``(Ac, Bc, Cc)`` is itself minimal: its poles, the eigenvalues of
        ``Ac``, are then computed once per input, and the zeros from the same realisation.
        Otherwise both come from the realisation :meth:`minimal` returns.
        """
        if self.plant.n_states == 0:
            return _siso_pz(self.entry(i, j))
        g, Ac, Bc, Cc, Qo = self._parts(i, j)
        if Qo.shape[1] < Ac.shape[0]:
            return _siso_pz(StateSpaceModel(Qo.T @ Ac @ Qo, Qo.T @ Bc, Cc @ Qo, g.D.copy(), g.dt))
        if j not in self._poles:
            self._poles[j] = np.linalg.eigvals(Ac)
        zeros = StateSpaceModel(Ac, Bc, Cc, g.D.copy(), g.dt).zeros(minimal=False)
        return self._poles[j].copy(), zeros


def cancel_entries(
    plant: StateSpaceModel,
    tol: float = 1e-2,
    f_ref_hz: float | None = None,
    minimal_tol: float | None = None,
    response: Callable[[np.ndarray], np.ndarray] | None = None,
) -> tuple[TransferMatrix, tuple[EntryPoleZero, ...]]:
    """Per entry of a deduced discrete plant: minimal SISO realisation, poles, zeros, cancellation.

    Parameters
    ----------
    plant : StateSpaceModel
        Discrete deduced plant (e.g. from :func:`~stageid.closedloop.deduction.deduce_plant`).
    tol : float
        Relative ``s``-plane distance below which a pole and a zero cancel.
    f_ref_hz : float, optional
        Frequency where the gain of the rebuilt entry is matched to the full model
        (default a tenth of the Nyquist frequency).
    minimal_tol : float, optional
        Rank tolerance of the SISO minimal realisations.
    response : callable, optional
        ``response(freqs_hz)`` -> the plant's response, shape (n_freqs, p, p), used to refit
        the numerators (default ``plant.frequency_response``).  The estimator passes eq. 18
        frequency by frequency: the large non-minimal realisation's own response loses
        accuracy at low frequencies (``z`` near 1).

    Returns
    -------
    (TransferMatrix, tuple of EntryPoleZero)
        The cancelled discrete transfer matrix and the per-entry report.

    Raises
    ------
    IdentificationError
        When the plant is continuous.
    """
    if plant.dt is None:
        raise IdentificationError("cancel_entries works on the discrete deduced plant; got a continuous model.")
    dt = plant.dt
    f_ref = 0.1 / (2 * dt) if f_ref_hz is None else float(f_ref_hz)
    f_grid = np.geomspace(max(f_ref / 100, 1e-3 / dt), 0.45 / dt, 400)
    G_grid = (plant.frequency_response if response is None else response)(f_grid)  # once for all entries
    reports = []
    num_rows, den_rows = [], []
    split = PlantEntries(plant, minimal_tol)
    for i in range(plant.n_outputs):
        nr, dr = [], []
        for j in range(plant.n_inputs):
            poles, zeros = split.poles_zeros(i, j)
            kp, kz, pairs = cancel_pairs(poles, zeros, dt, tol, i, j)
            # rebuild the numerator over a wide grid with the kept poles fixed (linear least squares on
            # the entry's own response): robust when a pencil zero of a large entry is inaccurate
            kz, gain = _refit_numerator(plant.dt, G_grid[:, i, j], kp, kz.size, f_grid)
            rep = EntryPoleZero(i, j, poles, zeros, kp, kz, gain, pairs)
            reports.append(rep)
            num, den = rep.polynomials()
            nr.append(num)
            dr.append(den)
        num_rows.append(nr)
        den_rows.append(dr)
    return TransferMatrix(num_rows, den_rows, dt, plant.inputs, plant.outputs), tuple(reports)


def _refit_numerator(
    dt: float, G: np.ndarray, kept_poles: np.ndarray, n_zeros: int, f_grid: np.ndarray
) -> tuple[np.ndarray, float]:
    """Zeros and gain of an entry with response ``G`` over ``f_grid``, given its kept poles:
    ``N(z) = G(z) D(z)`` fitted in the relative sense; the numerator degree is ``n_zeros``,
    raised if needed up to ``n_poles - 1`` (strictly proper) until the fit stops improving by 10x."""
    z = np.exp(2j * np.pi * f_grid * dt)
    den = np.real(np.poly(kept_poles)) if kept_poles.size else np.array([1.0])
    target = G * np.polyval(den, z)
    w = 1.0 / np.maximum(np.abs(target), 1e-300)
    best = None
    for deg in range(min(n_zeros, max(kept_poles.size - 1, 0)), max(kept_poles.size - 1, 0) + 1):
        V = np.vander(z, deg + 1) * w[:, None]
        b, *_ = np.linalg.lstsq(
            np.vstack([V.real, V.imag]), np.concatenate([(target * w).real, (target * w).imag]), rcond=None
        )
        err = float(np.max(np.abs(np.polyval(b, z) - target) * w))
        if best is None or err < 0.1 * best[0]:
            best = (err, b)
    b = best[1] if best is not None else np.array([0.0])
    nz = np.flatnonzero(np.abs(b) > 1e-14 * np.max(np.abs(b))) if np.any(b) else np.array([0])
    b = b[nz[0] :] if nz.size else b
    zeros = np.roots(b) if b.size > 1 else np.zeros(0, complex)
    return zeros, float(b[0])


def pole_contributions(plant: StateSpaceModel, poles_z: np.ndarray, freqs_hz: np.ndarray) -> np.ndarray:
    """How much each given pole contributes to each entry of a (non-minimal) discrete plant.

    For the mode ``lambda`` of ``A`` nearest to each pole, the residue of entry ``(i, j)``
    is ``R_ij = C_i v w^T B_j`` (``v``, ``w`` right/left eigenvectors, ``w^T v = 1``); its
    contribution is ``max_f |R_ij / (z - lambda)| / max_f |G_ij(z)|`` over ``freqs_hz``.
    A pole that an entry really has contributes O(1); a spurious copy that the deduction
    carries into an entry without it contributes only the identification error.

    Returns
    -------
    ndarray of shape (n_poles, n_outputs, n_inputs)
    """
    poles_z = np.asarray(poles_z, dtype=complex).reshape(-1)
    out = np.zeros((poles_z.size, plant.n_outputs, plant.n_inputs))
    if poles_z.size == 0 or plant.n_states == 0:
        return out
    A, T = sla.matrix_balance(plant.A, permute=False, separate=False)
    tdiag = T.diagonal()
    B = plant.B / tdiag[:, None]
    C = plant.C * tdiag[None, :]
    lam, V = np.linalg.eig(A)
    z = np.exp(2j * np.pi * np.asarray(freqs_hz, dtype=float) * plant.dt)
    G = plant.frequency_response(freqs_hz)
    scale = np.max(np.abs(G), axis=0)
    for k, pz in enumerate(poles_z):
        m = int(np.argmin(np.abs(lam - pz)))
        v = V[:, m]
        # left eigenvector of the same eigenvalue: null vector of (A - lam I)^T
        _, _, vh = np.linalg.svd((A - lam[m] * np.eye(A.shape[0])).T)
        w = vh[-1].conj()
        w = w / (w @ v)
        R = np.outer(C @ v, w @ B)
        contrib = np.max(np.abs(R[None, :, :] / (z[:, None, None] - lam[m])), axis=0)
        out[k] = contrib / np.maximum(scale, 1e-300)
    return out
