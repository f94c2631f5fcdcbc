"""Predictor-based subspace identification (PBSID) of the innovation form from closed-loop data.

The innovation form ``x(t+1) = A x + B u + K e``, ``y = C x + D u + e`` has the predictor
``x(t+1) = A~ x + B~ z``, ``z = [u; y]``, ``A~ = A - K C``, ``B~ = [B - K D, K]``, which is
stable even when ``A`` is not.  Its Markov parameters ``Xi_k = C A~^(k-1) B~`` follow from a
high-order VARX regression of ``y(t)`` on the past ``z(t-1) ... z(t-p)``; that regression stays
consistent in closed loop because the innovation ``e(t)`` is uncorrelated with the past of
``u`` and ``y`` whenever the loop holds a delay (Chiuso & Picci, Automatica 41, 2005; Chiuso,
Automatica 43, 2007, "PBSID").  The state follows from an SVD of ``Gamma_f K_p Z_p`` (the
"optimised" form of van der Veen, van Wingerden & Verhaegen, IFAC 2010), then ``C, D`` and
``A, B, K`` from two least-squares regressions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import IdentificationError

__all__ = ["InnovationMatrices", "past_windows", "varx", "choose_horizon", "pbsid", "order_by_bic"]


@dataclass(frozen=True)
class InnovationMatrices:
    """``x(t+1) = A x + B u + b0 + K e``, ``y = C x + D u + d0 + e`` and the innovation covariance ``Lambda``.

    The offsets ``b0`` (state) and ``d0`` (output) absorb the operating point: removing the
    records' means is not enough for an unstable plant, whose mean output is not ``G(1)`` times
    its mean input over a finite record.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    K: np.ndarray
    noise_cov: np.ndarray
    state_offset: np.ndarray | None = None
    output_offset: np.ndarray | None = None

    @property
    def predictor_poles(self) -> np.ndarray:
        """Eigenvalues of ``A - K C`` (inside the unit circle for a usable predictor)."""
        return np.linalg.eigvals(self.A - self.K @ self.C)


def past_windows(z: np.ndarray, p: int) -> np.ndarray:
    """Rows ``[z(t-p), ..., z(t-1)]`` for ``t = p .. N`` (the last row predicts one step past the data).

    Returns ndarray of shape (N - p + 1, p * n_z).
    """
    n, nz = z.shape
    out = np.empty((n - p + 1, p * nz))
    for j in range(p):
        out[:, j * nz : (j + 1) * nz] = z[j : n - p + 1 + j]
    return out


def _regressors(records: Sequence[tuple[np.ndarray, np.ndarray]], p: int, feedthrough: bool):
    """Stacked VARX regressors ``[Z_p, u(t)]`` and targets ``y(t)`` over all records."""
    phis, ys = [], []
    for u, y in records:
        Z = past_windows(np.hstack([u, y]), p)[:-1]
        phis.append(np.hstack([Z, u[p:]]) if feedthrough else Z)
        ys.append(y[p:])
    return np.vstack(phis), np.vstack(ys)


def varx(records: Sequence[tuple[np.ndarray, np.ndarray]], p: int, feedthrough: bool):
    """Least-squares VARX of order ``p``: ``(Xi, D, residual covariance, n_rows, rcond)``.

    ``Xi`` has shape (n_y, p * n_z), blocks ordered ``z(t-p) ... z(t-1)``; ``rcond`` is the
    reciprocal condition number of the regressor covariance, the data's persistence of
    excitation at this horizon.
    """
    Phi, Y = _regressors(records, p, feedthrough)
    if Phi.shape[0] <= Phi.shape[1]:
        raise IdentificationError(
            f"the past horizon {p} needs more than {Phi.shape[1]} usable samples; got {Phi.shape[0]}."
        )
    scale = np.std(Phi, axis=0)
    scale[scale == 0] = 1.0
    Q, R = np.linalg.qr(Phi / scale)
    sv = np.linalg.svd(R, compute_uv=False)
    rcond = float((sv[-1] / sv[0]) ** 2) if sv[0] > 0 else 0.0
    theta = np.linalg.lstsq(R, Q.T @ Y, rcond=None)[0] / scale[:, None]
    E = Y - Phi @ theta
    m = records[0][0].shape[1]
    nzp = Phi.shape[1] - (m if feedthrough else 0)
    Xi = theta[:nzp].T
    D = theta[nzp:].T if feedthrough else np.zeros((Y.shape[1], m))
    return Xi, D, E.T @ E / E.shape[0], Phi.shape[0], rcond


def choose_horizon(records, candidates: Sequence[int], feedthrough: bool) -> int:
    """The past horizon of smallest BIC, ``N log det Lambda + k log N``, among ``candidates``."""
    best, best_bic = None, np.inf
    for p in candidates:
        try:
            Xi, D, L, n, _ = varx(records, p, feedthrough)
        except IdentificationError:
            continue
        sign, logdet = np.linalg.slogdet(L)
        if sign <= 0:
            continue
        bic = n * logdet + (Xi.size + D.size) * np.log(n)
        if bic < best_bic:
            best, best_bic = p, bic
    if best is None:
        raise IdentificationError(f"no past horizon among {list(candidates)} fits the records; they are too short.")
    return int(best)


def _gamma_k(Xi: np.ndarray, p: int, nz: int) -> np.ndarray:
    """``Gamma_p K_p`` from the predictor's Markov parameters, ``A~^p`` neglected (block row i shifted by i)."""
    ny = Xi.shape[0]
    out = np.zeros((p * ny, p * nz))
    for i in range(p):
        out[i * ny : (i + 1) * ny, i * nz :] = Xi[:, : (p - i) * nz]
    return out


def _states(records, Xi, p, n, nz):
    """State sequences ``x(t) = S^-1/2 U' Gamma K Z_p(t)`` per record and the singular values."""
    GK = _gamma_k(Xi, p, nz)
    Zs = [past_windows(np.hstack([u, y]), p) for u, y in records]
    Zall = np.vstack(Zs)
    Rz = np.linalg.qr(Zall, mode="r") / np.sqrt(Zall.shape[0])
    U, s, _ = np.linalg.svd(GK @ Rz.T, full_matrices=False)
    if n > s.size or s[n - 1] <= 1e-12 * s[0]:
        raise IdentificationError(f"the data support fewer than {n} states (singular values {s[: n + 1]}).")
    T = U[:, :n].T / np.sqrt(s[:n])[:, None]
    return [Z @ (T @ GK).T for Z in Zs], s


def pbsid(records: Sequence[tuple[np.ndarray, np.ndarray]], n: int, p: int, feedthrough: bool) -> InnovationMatrices:
    """Innovation-form matrices of order ``n`` from ``(u, y)`` records, past horizon ``p``.

    Raises
    ------
    IdentificationError
        Too short records, or data that support fewer than ``n`` states.
    """
    m, ny = records[0][0].shape[1], records[0][1].shape[1]
    Xi, _, _, _, _ = varx(records, p, feedthrough)
    X, _ = _states(records, Xi, p, n, m + ny)
    # C, D from y(t) = C x(t) + D u(t) + e(t); A, B, K from x(t+1) = A x + B u + K e
    xs = np.vstack([x[:-1] for x in X])
    us = np.vstack([u[p:] for u, _ in records])
    ys = np.vstack([y[p:] for _, y in records])
    reg = np.hstack([xs, us]) if feedthrough else xs
    CD = np.linalg.lstsq(reg, ys, rcond=None)[0].T
    C = CD[:, :n]
    D = CD[:, n:] if feedthrough else np.zeros((ny, m))
    E = ys - reg @ CD.T
    # the windows run one step past each record, so x(t+1) exists for every regression row
    x_next = np.vstack([x[1:] for x in X])
    reg2 = np.hstack([xs, us, E])
    ABK = np.linalg.lstsq(reg2, x_next, rcond=None)[0].T
    A, B, K = ABK[:, :n], ABK[:, n : n + m], ABK[:, n + m :]
    return InnovationMatrices(A, B, C, D, K, E.T @ E / E.shape[0])


def singular_values(records, p: int, feedthrough: bool) -> np.ndarray:
    """Singular values of ``Gamma K Z_p`` (the order's evidence)."""
    m, ny = records[0][0].shape[1], records[0][1].shape[1]
    Xi = varx(records, p, feedthrough)[0]
    return _states(records, Xi, p, 1, m + ny)[1]


def order_by_bic(records, p: int, orders: Sequence[int], feedthrough: bool, residuals) -> int:
    """The order of smallest BIC of the PBSID start's one-step prediction (``residuals(mats)`` pooled)."""
    m, ny = records[0][0].shape[1], records[0][1].shape[1]
    best, best_bic = None, np.inf
    for n in orders:
        try:
            mats = pbsid(records, n, p, feedthrough)
        except IdentificationError:
            break
        if np.max(np.abs(mats.predictor_poles)) >= 1:
            continue
        E = residuals(mats)
        sign, logdet = np.linalg.slogdet(E.T @ E / E.shape[0])
        k = n * (n + 2 * ny + m) + (ny * m if feedthrough else 0) - n * n  # similarity removes n^2
        bic = E.shape[0] * logdet + k * np.log(E.shape[0])
        if sign > 0 and bic < best_bic:
            best, best_bic = n, bic
    if best is None:
        raise IdentificationError(f"no order among {list(orders)} gives a stable predictor on these records.")
    return int(best)
