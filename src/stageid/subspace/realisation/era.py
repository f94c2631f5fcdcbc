"""Reconstruction of the system matrices, Cao & Chen (2013) sections 2.1-2.2.

From the identified ``theta = [Gamma Phi D_p]`` (eq. 9):

* ``H0 = Gamma + Phi D_p = C_p B_p`` (eq. 10) and ``H_i = Phi^i H0 = C_p A^(i p) B_p`` (eq. 12);
* the Markov parameters ``Y_0 = D, Y_k = C A^(k-1) B``: ``Y_0 .. Y_(p-1)`` are the first block
  column of ``D_p`` and ``Y_(p(t+1)+i)`` is block ``(i, 0)`` of ``H_t`` (block ``(i, j)`` of
  ``H_t`` is ``Y_(tp+p+i-j)``: eq. 4 orders ``B_p`` from ``A^(p-1) B`` down to ``B``);
* the Hankel matrices ``H(0)``, ``H(1)`` of eq. 14 and the realisation of Lemma 1 (eq. 15):
  ``A = S^-1/2 U^T H(1) V S^-1/2``, ``B`` the first ``m`` columns of ``S^1/2 V^T``, ``C`` the
  first ``q`` rows of ``U S^1/2`` (:func:`era`).

:func:`realize` is the realisation step of ``HankelMAP``: on the noise-whitened outputs (see
:mod:`.weighting`) it runs the route picked by name from :data:`REALIZATIONS`:
:func:`markov_realization` (the paper's eq. 10-15, exact for broadband inputs) or
:func:`~stageid.subspace.realisation.frequency_domain.response_realization` (the response of eq. 9 over
the excited band, realised and refined: band-limited records determine ``theta`` only up to
directions without input energy, and those enter the Markov parameters).
"""

from __future__ import annotations

import numpy as np

from ..._errors import IdentificationError
from ...models.statespace import StateSpaceModel
from ..map.posterior import Posterior
from ..statistics.hankel_toeplitz import split_theta
from .frequency_domain import response_realization
from .route import RouteTask
from .weighting import output_weights, weighted_theta

__all__ = [
    "hankel_h0",
    "hankel_hi",
    "markov_from_theta",
    "hankel_matrices",
    "era",
    "markov_realization",
    "realize",
    "REALIZATIONS",
]


def hankel_h0(theta: np.ndarray, horizon: int, n_inputs: int, n_outputs: int) -> np.ndarray:
    """``H0 = Gamma + Phi D_p`` (eq. 10), shape (p q, p m)."""
    Gam, Phi, Dp = split_theta(theta, horizon, n_inputs, n_outputs)
    return Gam + Phi @ Dp


def hankel_hi(theta: np.ndarray, horizon: int, n_inputs: int, n_outputs: int, i: int) -> np.ndarray:
    """``H_i = Phi^i H0 = C_p A^(i p) B_p`` (eq. 11-12), shape (p q, p m)."""
    _, Phi, _ = split_theta(theta, horizon, n_inputs, n_outputs)
    H = hankel_h0(theta, horizon, n_inputs, n_outputs)
    for _ in range(i):
        H = Phi @ H
    return H


def markov_from_theta(theta: np.ndarray, horizon: int, n_inputs: int, n_outputs: int, n_parameters: int) -> np.ndarray:
    """Markov parameters ``Y_0`` to ``Y_(n-1)`` of the identified Hankel-Toeplitz model.

    Returns
    -------
    ndarray of shape (n_parameters, n_outputs, n_inputs)

    Examples
    --------
    >>> import numpy as np
    >>> p, m, q = 2, 1, 1
    >>> theta = np.zeros((p * q, 2 * p * m + p * q)); theta[1, 4] = 0.5   # Y_1 = 0.5
    >>> markov_from_theta(theta, p, m, q, 3)[:, 0, 0].tolist()
    [0.0, 0.5, 0.0]
    """
    p, m, q = horizon, n_inputs, n_outputs
    _, Phi, Dp = split_theta(theta, p, m, q)
    out = np.zeros((n_parameters, q, m))
    for i in range(min(p, n_parameters)):
        out[i] = Dp[i * q : (i + 1) * q, :m]
    H = hankel_h0(theta, p, m, q)
    k = p
    while k < n_parameters:
        for i in range(p):
            if k + i < n_parameters:
                out[k + i] = H[i * q : (i + 1) * q, :m]
        H = Phi @ H
        k += p
    return out


def hankel_matrices(markov: np.ndarray, n1: int, n2: int) -> tuple[np.ndarray, np.ndarray]:
    """``H(0)`` and ``H(1)`` of eq. 14 from Markov parameters ``Y_k`` (``Y_1 = CB``).

    Parameters
    ----------
    markov : ndarray of shape (n_parameters, q, m)
        ``Y_0 = D, Y_1 = CB, ...``; needs ``n_parameters >= n1 + n2 + 3``.
    n1, n2 : int
        Block columns ``n1 + 1`` and block rows ``n2 + 1``.

    Returns
    -------
    H0, H1 : ndarrays of shape ((n2 + 1) q, (n1 + 1) m)
    """
    if markov.shape[0] < n1 + n2 + 3:
        raise IdentificationError(
            f"eq. 14 with n1={n1}, n2={n2} needs {n1 + n2 + 3} Markov parameters; got {markov.shape[0]}."
        )
    H0 = np.block([[markov[1 + i + j] for j in range(n1 + 1)] for i in range(n2 + 1)])
    H1 = np.block([[markov[2 + i + j] for j in range(n1 + 1)] for i in range(n2 + 1)])
    return H0, H1


def era(
    markov: np.ndarray, order: int, n1: int | None = None, n2: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Realisation of Lemma 1 (eq. 15) from Markov parameters.

    Parameters
    ----------
    markov : ndarray of shape (n_parameters, q, m)
    order : int
        ``s`` of Lemma 1, ``s <= min(m (n1 + 1), q (n2 + 1))``.
    n1, n2 : int, optional
        Hankel size; default the largest square-ish size the Markov parameters allow.

    Returns
    -------
    A, B, C, D, singular_values
        ``D = Y_0``; ``singular_values`` are all singular values of ``H(0)``.

    Examples
    --------
    >>> import numpy as np
    >>> Y = np.array([0.0] + [0.5 * 0.8 ** (k - 1) for k in range(1, 30)])[:, None, None]
    >>> A, B, C, D, s = era(Y, 1)
    >>> round(float(A[0, 0]), 6)
    0.8
    """
    n_par, q, m = markov.shape
    if n1 is None or n2 is None:
        half = (n_par - 3) // 2
        n1 = half if n1 is None else n1
        n2 = half if n2 is None else n2
    limit = min(m * (n1 + 1), q * (n2 + 1))
    if not 1 <= order <= limit:
        raise IdentificationError(f"Lemma 1 needs 1 <= order <= min(m (n1+1), q (n2+1)) = {limit}; got {order}.")
    H0, H1 = hankel_matrices(markov, n1, n2)
    U, s, Vt = np.linalg.svd(H0, full_matrices=False)
    Us, Ss, Vs = U[:, :order], s[:order], Vt[:order].T
    if Ss[-1] <= 0:
        raise IdentificationError(f"H(0) has rank below the requested order {order}.")
    si = 1.0 / np.sqrt(Ss)
    A = (si[:, None] * (Us.T @ H1 @ Vs)) * si[None, :]
    sq = np.sqrt(Ss)
    B = (sq[:, None] * Vs.T)[:, :m]
    C = (Us * sq[None, :])[:q]
    return A, B, C, markov[0].copy(), s


def markov_realization(task: RouteTask) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """``realization="markov"``, the paper's route: eq. 10-12 Markov parameters, eq. 14, Lemma 1.

    ``Y_0 .. Y_(2p-1)`` come from ``D_p`` and ``H0`` (eq. 10); longer sequences only when the
    order needs them (``H_i = Phi^i H0``, eq. 12).  The task's ``freqs``, ``refine`` and
    ``max_iter`` are not used; the cost is NaN.
    """
    (p, m, q), order = task.shape, task.order
    n2 = int(np.ceil(order / q))
    n1 = max(int(np.ceil(order / m)), 2 * p - 3 - n2)
    Y = markov_from_theta(task.theta, p, m, q, n1 + n2 + 3)
    A, B, C, D, _ = era(Y, order, n1=n1, n2=n2)
    if not task.feedthrough:
        D = np.zeros_like(D)
    return A, B, C, D, float("nan")


#: ``realization`` of ``HankelMAP`` -> the route from ``theta`` (noise-whitened) to ``A, B, C, D``.
REALIZATIONS = {"frequency": response_realization, "markov": markov_realization}


def realize(
    post: Posterior,
    order: int,
    freqs: np.ndarray,
    dt: float,
    realization: str = "frequency",
    feedthrough: bool = False,
    refine: bool = True,
    max_iter: int = 30,
) -> tuple[StateSpaceModel, float]:
    """Eq. 10-15 or the frequency route: the ``order``-state model of the posterior mean ``theta``.

    The route runs on the noise-whitened outputs ``w * y`` (:func:`~.weighting.output_weights`),
    and the weights are undone on ``C`` and ``D``.  Returns the model (in the posterior's
    coordinates, without channel names) and the relative misfit of the refinement (NaN when
    there was none).
    """
    p, m, q = post.horizon, post.n_inputs, post.n_outputs
    w = output_weights(post)
    theta_w = weighted_theta(post.theta, w, p, m, q)
    task = RouteTask(theta_w, p, m, q, order, freqs, dt, feedthrough, refine, max_iter)
    A, B, C, D, cost = REALIZATIONS[realization](task)
    return StateSpaceModel(A, B, C / w[:, None], D / w[:, None], dt), cost
