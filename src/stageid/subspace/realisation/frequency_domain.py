"""The frequency route of the realisation: the response of eq. 9 over the excited band, realised.

Lemma 1 (eq. 15) needs the whole impulse response, which band-limited data do not determine
(inputs with no energy above 100 Hz leave the out-of-band part of every Markov parameter to
the prior).  :func:`frequency_realization` therefore realises the identified model from its
frequency response over the *excited* band (McKelvey, Akcay & Ljung 1996: the
frequency-domain counterpart of Lemma 1, an SVD of a Hankel-structured matrix followed by the
same shift-invariance step), then fits ``B`` and ``D`` by linear least squares on that band.
:func:`refine_from_starts` then fits all matrices to that response (output error,
:mod:`.refinement`), starting from the realisation or from :func:`balanced_start` (a
:func:`balanced_truncation` of a realisation of twice the order), whichever fits better.
:func:`response_realization` is the whole route.
"""

from __future__ import annotations

import numpy as np

from ..._errors import IdentificationError
from ..statistics.theta_response import theta_frequency_response
from .refinement import MULTI_START_MISFIT, REFINE_TOL, fit_cost, model_response, refine_frequency_fit
from .route import RouteTask

__all__ = [
    "frequency_realization",
    "fit_input_matrices",
    "balanced_truncation",
    "balanced_start",
    "reflect_unstable",
    "refine_from_starts",
    "response_realization",
]


def _resolvent_rows(A: np.ndarray, C: np.ndarray, zs: np.ndarray) -> np.ndarray:
    """``C (z I - A)^-1`` for every z, shape (n_z, q, n)."""
    n = A.shape[0]
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) < 1e8:
        CVz = ((C @ V)[None, :, :] * (1.0 / (zs[:, None] - lam[None, :]))[:, None, :]).reshape(-1, n)
        return (CVz @ np.linalg.inv(V)).reshape(zs.size, C.shape[0], n)  # one product over all z
    eye = np.eye(n)
    return np.stack([np.linalg.solve((zk * eye - A).T, C.T).T for zk in zs])


def fit_input_matrices(
    A: np.ndarray,
    C: np.ndarray,
    G: np.ndarray,
    zs: np.ndarray,
    feedthrough: bool = True,
    weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares ``B``, ``D`` with ``C (zI - A)^-1 B + D ~= G`` at the given points.

    Parameters
    ----------
    A : (n, n); C : (q, n); G : (n_z, q, m) complex; zs : (n_z,) complex
    feedthrough : bool
        Estimate ``D`` (else ``D = 0``).
    weights : ndarray of shape (n_z,), optional
        Non-negative weight of each frequency point.

    Returns
    -------
    B : ndarray of shape (n, m); D : ndarray of shape (q, m)
    """
    n = A.shape[0]
    nz, q, m = G.shape
    R = _resolvent_rows(A, C, zs)  # (nz, q, n)
    cols = [R]
    if feedthrough:
        cols.append(np.broadcast_to(np.eye(q), (nz, q, q)))
    M = np.concatenate(cols, axis=2).reshape(nz * q, -1)
    rhs = G.reshape(nz * q, m)
    if weights is not None:
        w = np.repeat(np.sqrt(weights), q)[:, None]
        M = M * w
        rhs = rhs * w
    Mr = np.vstack([M.real, M.imag])
    rr = np.vstack([rhs.real, rhs.imag])
    sol = np.linalg.lstsq(Mr, rr, rcond=None)[0]
    B = sol[:n]
    D = sol[n:] if feedthrough else np.zeros((q, m))
    return B, D


def frequency_realization(
    G: np.ndarray,
    freqs: np.ndarray,
    dt: float,
    order: int,
    block_rows: int | None = None,
    feedthrough: bool = True,
    weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """State-space realisation from frequency-response samples (McKelvey et al. 1996).

    With ``W_r(z) = [1, z, ..., z^(r-1)]^T`` the data matrices ``Y = [W_r(z_k) (x) G_k]_k`` and
    ``U = [W_r(z_k) (x) I_m]_k`` satisfy ``Y = O_r X + T_r U`` (``O_r`` the extended
    observability matrix).  Removing ``U`` by an LQ factorisation of the real-valued data and
    taking the dominant ``order`` left singular vectors gives ``O_r``; ``A`` and ``C`` follow by
    shift invariance exactly as in Lemma 1, and ``B``, ``D`` by linear least squares on ``G``.

    Parameters
    ----------
    G : ndarray of shape (n_freqs, q, m), complex
    freqs : ndarray of shape (n_freqs,)
        Frequencies in Hz (any subset of ``[0, 1/(2 dt)]``: the excited band).
    dt : float
    order : int
    block_rows : int, optional
        ``r > order / q``; default ``max(order + 1, 2 ceil(order / q) + 2)`` capped so the
        problem stays overdetermined.
    feedthrough : bool
    weights : ndarray of shape (n_freqs,), optional
        Non-negative weight of each frequency: the columns of ``Y`` and ``U`` that belong to
        frequency ``k`` are scaled by ``sqrt(w_k)`` (the relation ``Y = O_r X + T_r U`` holds
        column by column, so the scaled data keep it), and ``B``, ``D`` are fitted with the
        same weights.  Noise-only lines then no longer bend the subspace.

    Returns
    -------
    A, B, C, D, singular_values

    Raises
    ------
    IdentificationError
        When there are too few frequency points for the order.

    Examples
    --------
    >>> import numpy as np
    >>> f = np.linspace(1, 200, 100); z = np.exp(2j * np.pi * f * 0.002)
    >>> G = (0.2 / (z - 0.8))[:, None, None]
    >>> A, B, C, D, s = frequency_realization(G, f, 0.002, 1)
    >>> round(float(A[0, 0]), 6)
    0.8
    """
    nf, q, m = G.shape
    if order < 1:
        raise IdentificationError(f"the model order must be >= 1; got {order}.")
    r = block_rows or max(order + 1, 2 * int(np.ceil(order / q)) + 2)
    r = int(min(r, max(2, (2 * nf * m) // (m + q) - 1)))
    if r * q < order + q or 2 * nf * m < r * (m + q):
        raise IdentificationError(
            f"frequency realisation of order {order} needs more frequency points than {nf} for {q} outputs and {m} inputs."
        )
    zs = np.exp(2j * np.pi * np.asarray(freqs, dtype=float) * dt)
    Us, s = _observability_basis(G, zs, r, weights)
    if order > Us.shape[1]:
        raise IdentificationError(f"order {order} exceeds the {Us.shape[1]} available singular values.")
    O = Us[:, :order]
    C = O[:q]
    A = np.linalg.lstsq(O[:-q], O[q:], rcond=None)[0]
    B, D = fit_input_matrices(A, C, G, zs, feedthrough, weights)
    return A, B, C, D, s


def _observability_basis(
    G: np.ndarray, zs: np.ndarray, r: int, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Left singular vectors and values of ``Y`` with the row space of ``U`` removed
    (:func:`frequency_realization`), ``Y = [W_r(z_k) (x) G_k]``, ``U = [W_r(z_k) (x) I_m]``.

    ``U`` is ``W = [W_r(z_k)]_k`` once per input column, so the projection runs column by
    column against one orthonormal basis of ``W``'s rows (real and imaginary parts side by
    side), and the singular pairs come from the ``rq x rq`` Gram matrix of the projected ``Y``:
    the same subspace as the LQ factorisation of ``[U; Y]`` (McKelvey et al. 1996) at a third
    of its cost for ``r = 2n + 1``.  ``weights`` scale frequency ``k``'s columns of both by
    ``sqrt(w_k)``.
    """
    nf, q, m = G.shape
    powers = zs[None, :] ** np.arange(r)[:, None]  # (r, nf)
    if weights is not None:
        powers = powers * np.sqrt(np.asarray(weights, dtype=float))[None, :]
    Wr = np.hstack([powers.real, powers.imag])  # (r, 2 nf)
    Qw = np.linalg.qr(Wr.T)[0]  # (2 nf, r)
    gram = np.zeros((r * q, r * q))
    for j in range(m):
        Yj = (powers[:, :, None] * G[None, :, :, j]).transpose(0, 2, 1).reshape(r * q, nf)  # rows (k, output)
        Yr = np.hstack([Yj.real, Yj.imag])
        Yr -= (Yr @ Qw) @ Qw.T
        gram += Yr @ Yr.T
    ev, V = np.linalg.eigh(gram)
    desc = np.argsort(ev)[::-1]
    return V[:, desc], np.sqrt(np.clip(ev[desc], 0.0, None))


def _discrete_gramian(A: np.ndarray, Q: np.ndarray, max_doublings: int = 64) -> np.ndarray | None:
    """``X = sum_k A^k Q A^k^T`` (``X = A X A^T + Q``) by squared Smith iteration, for a stable ``A``.

    ``X_(j+1) = X_j + A_j X_j A_j^T`` with ``A_(j+1) = A_j^2`` doubles the number of terms per
    step: ``log2(log(eps) / log(rho(A)))`` steps (16 at ``rho = 0.9995``).  None when the sum
    has not converged (``A`` not stable: its powers overflow or do not vanish).
    """
    X = np.array(Q, dtype=float)
    Ak = np.array(A, dtype=float)
    for _ in range(max_doublings):
        X = X + Ak @ X @ Ak.T
        Ak = Ak @ Ak
        size = np.max(np.abs(Ak), initial=0.0)
        if not size < 1e100:  # growing (unstable) or not finite: stop before overflow
            return None
        if size < 1e-17:
            return 0.5 * (X + X.T)
    return None


def balanced_truncation(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, order: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Balanced truncation of a stable discrete-time ``(A, B, C)`` to ``order`` states.

    Square-root method (Laub et al. 1987): with the Gramians ``P = Lp Lp^T`` (controllability)
    and ``Q = Lq Lq^T`` (observability) and the SVD ``Lq^T Lp = U S V^T``, the truncated model
    is ``(Ti A T, Ti B, C T)`` with ``T = Lp V_r S_r^-1/2``, ``Ti = S_r^-1/2 U_r^T Lq^T``.  Its
    error is at most twice the sum of the discarded Hankel singular values ``S``.

    Returns
    -------
    ``(A_r, B_r, C_r, hankel_singular_values)``, or None when ``A`` is not stable or the kept
    Hankel singular values are not significant (< 1e-12 of the largest).

    Examples
    --------
    >>> import numpy as np
    >>> A = np.diag([0.9, 0.5, 0.1]); B = np.array([[1.0], [0.1], [1e-4]]); C = np.array([[1.0, 1.0, 1.0]])
    >>> Ar, Br, Cr, hsv = balanced_truncation(A, B, C, 1)
    >>> bool(abs(np.linalg.eigvals(Ar)[0] - 0.9) < 0.01)
    True
    """
    if A.size and np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        return None
    P = _discrete_gramian(A, B @ B.T)
    Q = None if P is None else _discrete_gramian(A.T, C.T @ C)
    if P is None or Q is None:
        return None
    wp, Vp = np.linalg.eigh(P)
    wq, Vq = np.linalg.eigh(Q)
    Lp = Vp * np.sqrt(np.clip(wp, 0.0, None))
    Lq = Vq * np.sqrt(np.clip(wq, 0.0, None))
    U, hsv, Vt = np.linalg.svd(Lq.T @ Lp)
    if order > hsv.size or hsv[0] <= 0 or hsv[order - 1] < 1e-12 * hsv[0]:
        return None
    root = hsv[:order] ** -0.5
    T = (Lp @ Vt[:order].T) * root[None, :]
    Ti = root[:, None] * (U[:, :order].T @ Lq.T)
    return Ti @ A @ T, Ti @ B, C @ T, hsv


def balanced_start(
    G: np.ndarray, freqs: np.ndarray, dt: float, order: int, feedthrough: bool = True, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """A starting realisation of ``order`` states: :func:`frequency_realization` of twice the
    order, reduced by :func:`balanced_truncation`, then ``B``, ``D`` fitted again on ``G``.

    The over-sized subspace fit absorbs what an ``order``-state one cannot fit; the truncation
    keeps the dominant part, so on white-input records the refinement starts far closer to
    its end (figures: ``benchmarks/RESULTS-subspace.md``).  On band-limited records the
    truncation, which weighs all frequencies alike, can start worse: the caller keeps the
    better start.  ``weights``: per-frequency weights of both fits (see
    :func:`frequency_realization`).

    Returns None when the larger realisation is not possible (too few frequencies) or not stable.
    """
    try:
        A, B, C, D, _ = frequency_realization(G, freqs, dt, 2 * order, feedthrough=feedthrough, weights=weights)
    except (IdentificationError, np.linalg.LinAlgError):
        return None
    try:
        red = balanced_truncation(A, B, C, order)
        if red is None:
            return None
        Ar, _, Cr, _ = red
        zs = np.exp(2j * np.pi * np.asarray(freqs, dtype=float) * dt)
        Br, Dr = fit_input_matrices(Ar, Cr, G, zs, feedthrough, weights)
    except np.linalg.LinAlgError:  # an SVD or eigensolver that does not converge: no start
        return None
    if not all(np.all(np.isfinite(x)) for x in (Ar, Br, Cr, Dr)):
        return None
    return Ar, Br, Cr, Dr


def reflect_unstable(A: np.ndarray) -> np.ndarray:
    """Mirror eigenvalues outside the unit circle to ``1 / conj(lambda)`` (real similarity kept)."""
    w, V = np.linalg.eig(A)
    bad = np.abs(w) >= 1.0
    w = np.where(bad, 0.999 * w / np.abs(w) ** 2, w)
    A2 = (V @ np.diag(w) @ np.linalg.inv(V)).real
    return A2


def refine_from_starts(
    abcd: tuple[np.ndarray, ...],
    Gs: np.ndarray,
    freqs: np.ndarray,
    dt: float,
    order: int,
    feedthrough: bool,
    max_iter: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Output-error refinement from the better of two starts; returns ``A, B, C, D`` and the
    cost relative to the response's energy.

    The starts are the direct realisation ``abcd`` and :func:`balanced_start` (far closer on
    white-input records).  The refinement runs from the one with the lower cost; when the
    result still misses the response by more than ``MULTI_START_MISFIT`` of its energy (the
    order cannot fit the system), it also runs from the other start and keeps the better end.
    """
    zs = np.exp(2j * np.pi * freqs * dt)
    energy = max(float(np.sum(np.abs(Gs) ** 2)), 1e-300)
    starts = [abcd]
    alt = balanced_start(Gs, freqs, dt, order, feedthrough)
    if alt is not None:
        starts.append(alt)
    # each start's response serves both its cost and the first step of its refinement
    starts = [(s, model_response(s, zs)) for s in starts]
    if len(starts) > 1:
        starts.sort(key=lambda s: fit_cost(s[0], Gs, zs, s[1]))
    best = None
    for k, (start, response) in enumerate(starts):
        if k and best[4]["cost"] <= MULTI_START_MISFIT * energy:
            break
        kw = {} if response is None else {"response": response}
        out = refine_frequency_fit(*start, Gs, zs, feedthrough=feedthrough, max_iter=max_iter, tol=REFINE_TOL, **kw)
        if best is None or out[4]["cost"] < best[4]["cost"]:
            best = out
    assert best is not None
    A, B, C, D, info = best
    return A, B, C, D, info["cost"] / energy


def response_realization(task: RouteTask) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """``realization="frequency"``: the response of eq. 9 over ``freqs``, realised and refined.

    Each input column of the response is scaled to a unit peak for the realisation and
    scaled back on ``B`` and ``D``; an unstable realisation has its unstable poles reflected
    (``B``, ``D`` fitted again) before the refinement.  Returns ``A, B, C, D`` and the
    relative misfit of the refinement (NaN without it).
    """
    freqs, dt, order, feedthrough = task.freqs, task.dt, task.order, task.feedthrough
    G = theta_frequency_response(task.theta, *task.shape, freqs, dt)
    scale = np.max(np.abs(G), axis=(0, 1))
    scale = np.where(scale > 0, scale, 1.0)
    Gs = G / scale[None, None, :]
    zs = np.exp(2j * np.pi * freqs * dt)
    A, B, C, D, _ = frequency_realization(Gs, freqs, dt, order, feedthrough=feedthrough)
    if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        A = reflect_unstable(A)
        B, D = fit_input_matrices(A, C, Gs, zs, feedthrough)
    cost = float("nan")
    if task.refine:
        A, B, C, D, cost = refine_from_starts((A, B, C, D), Gs, freqs, dt, order, feedthrough, task.max_iter)
    if not np.all(np.isfinite(A)) or not np.all(np.isfinite(B)):
        raise IdentificationError(f"the realisation of order {order} is not finite.")
    return A, B * scale[None, :], C, D * scale[None, :], cost
