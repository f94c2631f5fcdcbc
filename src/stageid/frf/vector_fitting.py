"""Vector fitting: common poles of a MIMO frequency response by iterated pole relocation.

Gustavsen & Semlyen (IEEE Trans. Power Delivery 14(3), 1999), in discrete time on the unit
circle.  With the poles ``a_k`` of the last iteration and the real basis ``phi_k(z)`` (``1 / (z - a)``
for a real pole; ``1 / (z - a) + 1 / (z - a*)`` and ``j / (z - a) - j / (z - a*)`` for a pair),
every entry is fitted linearly by

    sigma(z) G_ij(z) ~= sum_k r_ijk phi_k(z) + d_ij,    sigma(z) = 1 + sum_k s_k phi_k(z)

(weighted least squares over the lines, ``sigma`` shared by all entries); the zeros of ``sigma``
are the new poles (eigenvalues of ``A_p - b s^T``, eq. A.2 of the paper), unstable ones
reflected into the unit disc.  Unlike a subspace fit it weighs the lines as the output-error
cost does, so a weak mode between strong ones keeps its pole; it is the linearised
(Sanathanan-Koerner) form of the same cost.

:func:`vector_fit_start` turns the poles into the ``(A, C)`` of a real model of the fit's
order: each pole's residue matrix reduced to its dominant output direction (one state per
pole, the order of the model class); ``B`` and ``D`` are left to a linear fit.
"""

from __future__ import annotations

import numpy as np

__all__ = ["vector_fit_poles", "vector_fit_start", "initial_poles"]

#: Pole relocations of :func:`vector_fit_poles` (it stops earlier once the poles settle): the
#: poles of a start need not be exact, the refinement takes them the rest of the way.
VF_ITER = 10
#: Poles within this distance of the last iteration's (on the unit-circle scale) have settled.
VF_SETTLED = 1e-8


def initial_poles(zs: np.ndarray, order: int) -> np.ndarray:
    """``order`` starting poles: lightly damped pairs (1 % of their angle) at angles spread
    log-evenly over the band's, and one real pole at its middle when ``order`` is odd."""
    theta = np.angle(zs)
    lo, hi = max(float(theta.min()), 1e-6), max(float(theta.max()), 2e-6)
    n_pairs = order // 2
    angles = np.geomspace(lo, hi, n_pairs) if n_pairs > 1 else np.array([np.sqrt(lo * hi)])[:n_pairs]
    pairs = np.exp(-0.01 * angles + 1j * angles)
    poles = np.concatenate([pairs, pairs.conj()]) if n_pairs else np.empty(0, complex)
    if order % 2:
        poles = np.append(poles, np.exp(-np.sqrt(lo * hi)))
    return poles


def _split(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The real poles and one of each complex pair (upper half plane)."""
    tol = 1e-12
    real = poles[np.abs(poles.imag) <= tol].real
    upper = poles[poles.imag > tol]
    return real, upper


def _basis(zs: np.ndarray, real: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The real-coefficient basis ``phi_k(z)`` at every point, (n_z, n_poles) complex."""
    cols = [1.0 / (zs - a) for a in real]
    for a in upper:
        g1, g2 = 1.0 / (zs - a), 1.0 / (zs - np.conj(a))
        cols += [g1 + g2, 1j * (g1 - g2)]
    return np.column_stack(cols) if cols else np.empty((zs.size, 0), complex)


def _relocated(real: np.ndarray, upper: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Zeros of ``sigma = 1 + sum s_k phi_k``: eigenvalues of ``A_p - b s^T`` (real block form)."""
    n = real.size + 2 * upper.size
    Ap, b = np.zeros((n, n)), np.zeros(n)
    Ap[: real.size, : real.size] = np.diag(real)
    b[: real.size] = 1.0
    for k, a in enumerate(upper):
        i = real.size + 2 * k
        Ap[i : i + 2, i : i + 2] = [[a.real, a.imag], [-a.imag, a.real]]
        b[i] = 2.0
    return np.linalg.eigvals(Ap - np.outer(b, s))


def _reflected(poles: np.ndarray) -> np.ndarray:
    """Poles on or outside the unit circle moved to ``0.999 / conj(a)`` (their mirror image)."""
    mag = np.abs(poles)
    return np.where(mag >= 1.0, 0.999 * poles / np.maximum(mag, 1e-300) ** 2, poles)


def _sigma_rows(G: np.ndarray, Phi: np.ndarray, sw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the least-squares problem that only involve ``sigma``'s coefficients: each
    entry's ``[Phi, 1, -G Phi] x = G`` reduced by a QR factorisation to the part that its own
    residues and feedthrough cannot absorb (fast vector fitting, Deschrijver et al. 2008)."""
    nz, q, m = G.shape
    n = Phi.shape[1]
    rows, rhs = [], []
    left = np.column_stack([Phi, np.ones(nz)]) * sw[:, None]
    for i in range(q):
        for j in range(m):
            g = G[:, i, j] * sw
            M = np.hstack([left, -g[:, None] * Phi])
            M = np.vstack([M.real, M.imag])
            Q, R = np.linalg.qr(np.column_stack([M, np.concatenate([g.real, g.imag])]))
            rows.append(R[n + 1 : 2 * n + 1, n + 1 : 2 * n + 1])
            rhs.append(R[n + 1 : 2 * n + 1, -1])
    return np.vstack(rows), np.concatenate(rhs)


def vector_fit_poles(G: np.ndarray, zs: np.ndarray, order: int, weights: np.ndarray | None = None) -> np.ndarray:
    """``order`` common poles of the response ``G`` (n_z, q, m) at the unit-circle points ``zs``.

    Relocates :func:`initial_poles` up to ``VF_ITER`` times (see the module docstring); each
    step weighs line ``k`` by ``weights[k]`` (default all 1).  The poles are inside the unit
    disc, closed under conjugation.

    Examples
    --------
    >>> import numpy as np
    >>> zs = np.exp(1j * np.linspace(0.05, 3.0, 200))
    >>> G = (1 / (zs - 0.9 * np.exp(0.6j)) + 1 / (zs - 0.9 * np.exp(-0.6j)))[:, None, None]
    >>> poles = vector_fit_poles(G, zs, 2)
    >>> bool(np.allclose(np.sort_complex(poles), [0.9 * np.exp(-0.6j), 0.9 * np.exp(0.6j)]))
    True
    """
    w = np.ones(zs.size) if weights is None else np.asarray(weights, dtype=float)
    sw = np.sqrt(w)
    poles = initial_poles(zs, order)
    for _ in range(VF_ITER):
        real, upper = _split(poles)
        Phi = _basis(zs, real, upper)
        R, r = _sigma_rows(G, Phi, sw)
        s = np.linalg.lstsq(R, r, rcond=None)[0]
        new = _reflected(_relocated(real, upper, s))
        # conjugate pairs exactly paired, so the next basis stays real
        new = np.where(np.abs(new.imag) <= 1e-12, new.real, new)
        settled = new.size == poles.size and np.max(np.abs(np.sort_complex(new) - np.sort_complex(poles))) < VF_SETTLED
        poles = new
        if settled:
            break
    return poles


def vector_fit_start(
    G: np.ndarray, zs: np.ndarray, order: int, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(A, C)`` of a real ``order``-state model with the vector-fitted poles, each pole's
    output direction the dominant left singular vector of its residue matrix (fitted on the
    final poles); None when the fit is not finite.  ``B`` and ``D`` are for the caller to fit."""
    poles = vector_fit_poles(G, zs, order, weights)
    real, upper = _split(poles)
    if real.size + 2 * upper.size != order or not np.all(np.isfinite(poles)):
        return None
    w = np.ones(zs.size) if weights is None else np.asarray(weights, dtype=float)
    sw = np.sqrt(w)
    nz, q, m = G.shape
    M = np.column_stack([_basis(zs, real, upper), np.ones(nz)]) * sw[:, None]
    rhs = (G * sw[:, None, None]).reshape(nz, q * m)
    X = np.linalg.lstsq(np.vstack([M.real, M.imag]), np.vstack([rhs.real, rhs.imag]), rcond=None)[0]
    A, C = np.zeros((order, order)), np.zeros((q, order))
    for k, a in enumerate(real):
        A[k, k] = a
        C[:, k] = np.linalg.svd(X[k].reshape(q, m))[0][:, 0]
    for k, a in enumerate(upper):
        i = real.size + 2 * k
        # alpha phi_1 + beta phi_2 = (alpha + j beta) / (z - a) + its conjugate
        residue = (X[i] + 1j * X[i + 1]).reshape(q, m)
        c = np.linalg.svd(residue)[0][:, 0]
        # the block [[Re a, Im a], [-Im a, Re a]] has eigenvector [1, j] for a: output direction c
        A[i : i + 2, i : i + 2] = [[a.real, a.imag], [-a.imag, a.real]]
        C[:, i], C[:, i + 1] = c.real, c.imag
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(C))):
        return None
    return A, C
