"""The recursion of eq. 17-18 sample by sample (Cao & Chen 2013, section 2.3), for streaming use.

:func:`recursive_map` runs eq. 17-18 window by window in compiled kernels
(:mod:`.kernels`); :func:`recursive_map_python` is its plain-numpy twin, which the tests
hold it to.  A fit never needs this loop: after all windows the recursion equals the batch
posterior of :func:`~stageid.subspace.map.posterior.batch_posterior`.  Per-window costs are
in ``benchmarks/RESULTS-subspace.md``.
"""

from __future__ import annotations

import numpy as np

from ..._errors import DataError

__all__ = ["recursive_map", "recursive_map_python", "run_recursion"]


def recursive_map_python(
    u: np.ndarray, y: np.ndarray, horizon: int, theta: np.ndarray, P: np.ndarray, forgetting: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Plain-numpy reference of eq. 17-18 (one window at a time); see :func:`recursive_map`."""
    m = u.shape[1]
    p = horizon
    z = np.hstack([u, y])
    theta = np.array(theta, dtype=float)
    P = np.array(P, dtype=float)
    for k in range(z.shape[0] - 2 * p + 1):
        # the window in eq. 9 order, x = [u_p(k); y_p(k); u_p(k+p)], yv = y_p(k+p) (channels fastest)
        past, future = z[k : k + p], z[k + p : k + 2 * p]
        x = np.concatenate([past[:, :m].ravel(), past[:, m:].ravel(), future[:, :m].ravel()])
        yv = future[:, m:].ravel()
        Px = P @ x
        g = Px / (forgetting + x @ Px)
        e = yv - theta @ x
        theta += np.outer(e, g)
        P = (P - np.outer(g, Px)) / forgetting
    return theta, P


def run_recursion(
    z: np.ndarray, p: int, m: int, q: int, theta: np.ndarray, P: np.ndarray, lam: float
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 17-18 over all windows of ``z``: the first ``d`` windows and the last (< ``DELAY``) in
    the one-window kernel, the others in groups of ``DELAY`` in the delayed-update kernel.

    The group form starts from ``P_0 x_j`` and subtracts the earlier windows' rank-1 terms;
    with a vague prior (huge ``P_0``) that difference cancels until the data dominate ``P``,
    so the first ``d`` windows always run one at a time (as in :func:`_blocked`).
    """
    # numba loads with the kernels, only when a recursion runs (`stageid --help` stays fast)
    from .kernels import DELAY, aligned_zeros, delayed_kernel, one_window_kernel

    d = P.shape[0]
    rows = theta.shape[0]
    n_windows = z.shape[0] - 2 * p + 1
    n0 = min(d, max(n_windows, 0))
    if n_windows - n0 >= 2 * DELAY:
        theta, P = one_window_kernel()(np.ascontiguousarray(z[: n0 + 2 * p - 1]), p, m, q, theta, P, lam)
        z = np.ascontiguousarray(z[n0:])
        n_windows -= n0
        dp = -(-d // 4) * 4  # rows padded to whole 4-wide vectors
        th = aligned_zeros((rows + rows % 2, dp))  # even row counts: the kernel takes rows in pairs
        th[:rows, :d] = theta
        Pw = aligned_zeros((d + d % 2, dp))
        Pw[:d, :d] = P
        X, Xn, A, An, V = (aligned_zeros((DELAY, dp)) for _ in range(5))
        Y, Yn, T, Tn, E = (np.zeros((DELAY, th.shape[0])) for _ in range(5))
        uf = np.ascontiguousarray(z[:, :m]).ravel()
        yf = np.ascontiguousarray(z[:, m:]).ravel()
        done = delayed_kernel()(uf, yf, z.shape[0], p, m, q, th, Pw, lam, X, Y, Xn, Yn, A, T, An, Tn, V, E)
        theta = np.ascontiguousarray(th[:rows, :d])
        P = np.ascontiguousarray(Pw[:d, :d])
        if done == n_windows:
            return theta, P
        z = np.ascontiguousarray(z[done:])
    return one_window_kernel()(z, p, m, q, theta, P, lam)


def recursive_map(
    u: np.ndarray,
    y: np.ndarray,
    horizon: int,
    theta: np.ndarray,
    P: np.ndarray,
    forgetting: float = 1.0,
    block: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Recursive MAP estimation (eq. 17-18) over the windows of a record.

    ``block=1`` runs eq. 17-18 window by window: every window's gain ``g``, residual ``E`` and
    normaliser come from the previous window's ``theta`` and ``P`` exactly as in the textbook
    update, but the rank-1 updates of ``theta`` and ``P`` are applied four windows at a time
    (delayed updates: one memory pass over ``theta`` and one over ``P`` per four windows, each
    pass also forming ``theta x`` and ``P x`` of the next four windows); the first ``d``
    windows and the last few run in a one-window fused kernel.  ``block=B > 1`` applies the
    same recursion ``B`` windows at a time in its exact block form (Woodbury identity):
    ``K = P X (W^-1 + X^T P X)^-1``, ``theta += (Y - theta X) K^T``,
    ``P = (P - K (P X)^T) / lambda^B`` with ``W = diag(lambda^-(1+i))`` -- the same
    estimate after every block (to rounding), computed with matrix products (slower than
    ``block=1`` at d = 190, see ``benchmarks/RESULTS-subspace.md``).  The first ``d`` windows are always processed one at a time (with a vague
    prior the block system is ill-conditioned until the data dominate ``P``).

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs)
    y : ndarray of shape (n_samples, n_outputs)
    horizon : int
        ``p``; windows ``k = 0 .. n_samples - 2p`` are processed in time order.
    theta : ndarray of shape (p q, 2 p m + p q)
        Current estimate (the prior mean ``theta_0`` at the start).
    P : ndarray of shape (d, d)
        Current covariance in units of the noise covariance (``P_0`` at the start).
    forgetting : float, default 1.0
        Exponential forgetting factor in (0, 1].
    block : int, default 1
        Windows per update (1: strictly one window at a time).

    Returns
    -------
    theta, P : the updated estimate and covariance (new arrays; the inputs are not modified).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal((300, 1)); y = np.convolve(u[:, 0], [0, 0.5])[:300, None]
    >>> th, P = recursive_map(u, y, 2, np.zeros((2, 6)), 1e6 * np.eye(6))
    >>> bool(abs(th[0, 4] - 0.0) < 1e-3)  # coefficient of u(k) in y(k): D = 0
    True
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if u.ndim != 2 or y.ndim != 2 or u.shape[0] != y.shape[0]:
        raise DataError(f"`u` and `y` must be 2-D with the same number of rows; got {u.shape} and {y.shape}.")
    m, q = u.shape[1], y.shape[1]
    d = 2 * horizon * m + horizon * q
    if theta.shape != (horizon * q, d) or P.shape != (d, d):
        raise DataError(
            f"`theta` must have shape {(horizon * q, d)} and `P` {(d, d)}; got {theta.shape} and {P.shape}."
        )
    if not 0.0 < forgetting <= 1.0:
        raise DataError(f"`forgetting` must be in (0, 1]; got {forgetting}.")
    if not (isinstance(block, (int, np.integer)) and block >= 1):
        raise DataError(f"`block` must be a positive integer; got {block!r}.")
    z = np.ascontiguousarray(np.hstack([u, y]))
    th = np.array(theta, dtype=float, order="C")
    PP = np.array(P, dtype=float, order="C")
    PP = 0.5 * (PP + PP.T)
    n_windows = z.shape[0] - 2 * horizon + 1
    if block == 1 or n_windows <= 0:
        return run_recursion(z, horizon, m, q, th, PP, float(forgetting))
    # the first d windows one at a time: a vague prior (huge P_0) makes the block system
    # I + X^T P X ill-conditioned until the data dominate P
    n0 = min(n_windows, d)
    th, PP = run_recursion(np.ascontiguousarray(z[: n0 + 2 * horizon - 1]), horizon, m, q, th, PP, float(forgetting))
    if n0 == n_windows:
        return th, PP
    return _blocked(z[n0:], horizon, m, q, th, PP, float(forgetting), int(block))


def _window_offsets(p: int, m: int, q: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time offsets and channels of every entry of x and y_p inside a window (eq. 9 order)."""
    pos = np.arange(p)
    t_x = np.concatenate([np.repeat(pos, m), np.repeat(pos, q), np.repeat(p + pos, m)])
    c_x = np.concatenate([np.tile(np.arange(m), p), m + np.tile(np.arange(q), p), np.tile(np.arange(m), p)])
    return t_x, c_x, np.repeat(p + pos, q), m + np.tile(np.arange(q), p)


def _blocked(
    z: np.ndarray, p: int, m: int, q: int, theta: np.ndarray, P: np.ndarray, lam: float, block: int
) -> tuple[np.ndarray, np.ndarray]:
    import scipy.linalg as sla

    t_x, c_x, t_y, c_y = _window_offsets(p, m, q)
    n_windows = z.shape[0] - 2 * p + 1
    for k0 in range(0, n_windows, block):
        B = min(block, n_windows - k0)
        ks = k0 + np.arange(B)
        X = z[t_x[:, None] + ks[None, :], c_x[:, None]]  # (d, B)
        Y = z[t_y[:, None] + ks[None, :], c_y[:, None]]  # (p q, B)
        PX = P @ X
        S = X.T @ PX
        S[np.diag_indices(B)] += lam ** (np.arange(B) + 1.0)
        K = sla.cho_solve(sla.cho_factor(S, lower=True, check_finite=False), PX.T, check_finite=False).T
        theta += (Y - theta @ X) @ K.T
        P -= K @ PX.T
        if lam != 1.0:
            P /= lam**B
        P = 0.5 * (P + P.T)
    return theta, P
