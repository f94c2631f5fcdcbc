"""Uncertainty of the *realised* Hankel-MAP model: the eq. 9 posterior carried through the realisation.

:meth:`HankelMAPResult.response_bands` gives the posterior spread of the eq. 9 response; the
model a user takes away is the ``order``-state realisation of that response (the frequency
route: an output-error fit of ``C (zI - A)^-1 B + D`` to the eq. 9 response on the band's
grid, :mod:`~stageid.subspace.realisation.frequency_domain`,
:mod:`~stageid.subspace.realisation.refinement`).  Two ways carry the posterior there:

* ``"delta"`` (first order, the default for the frequency route with refinement): the
  realisation is the weighted least-squares fit ``min sum_k ||(G_model(z_k) - G_9(z_k)) / s_j||^2``
  (``s_j`` the column scale of :func:`~stageid.subspace.realisation.frequency_domain.response_realization`), so to first
  order a perturbation ``dG_9`` of the eq. 9 response moves the model's parameters by
  ``dx = J^+ dG_9`` (``J`` the Jacobian of the model's response in ``A, B, C, D``; the
  pseudo-inverse drops the ``n^2`` similarity directions, which do not change the response)
  and its response anywhere by ``J(f) dx``.  ``dG_9 = L^+ dtheta V(z)`` (first order in the
  block-row equations of eq. 9, as in ``theta_response_std``); the covariance of ``dG_9``
  across the whole grid, and so ``Cov(dx)``, is the one the least-squares coefficients have
  under overlapping windows (:mod:`~stageid.subspace.statistics.window_covariance`, from lag statistics the fit keeps), or,
  when the fit kept none (``update``, forgetting, records shorter than ``8 p``), the
  matrix-normal ``p P (x) Sigma`` (``P`` times ``p`` for the overlap, as in ``response_bands``:
  a rough allowance, ~1.4x too wide in std on some stages);
* ``"sampling"``: draws of ``theta`` from that posterior, each realised by the very route
  and order of the fit (:func:`~stageid.subspace.realisation.era.realize`), the spread of their responses
  around the identified one.  Slower; for ``realization="markov"`` (Lemma 1, not a
  least-squares fit on a grid) and ``refine=False`` it is the default.

Per-input-channel fits (eq. 19-22) are independent (disjoint records): the stacked model's
column ``j`` is the ``j``-th sub-model's, with its own posterior.  The realisation's own bias
(an order that cannot follow the eq. 9 response, a compromise of the refinement) is added by
``bias="local"`` (the default of ``"delta"``): the misfit between the model and the eq. 9
response beyond its noise expectation, where it is significant (:mod:`.realisation_bias`).
The bias of the eq. 9 estimate itself (noisy past outputs as regressors, a finite horizon) is
not counted (measured in ``studies/uncertainty/RESULTS.md``).

This package:

===========================  ================================================================
module                       what it holds
===========================  ================================================================
``__init__`` (here)          ``realised_response_uncertainty`` (delta method or draws),
                             ``model_jacobian``, ``response_std``
:mod:`.grid_placement`       where the realised model's covariance is formed: a few of the
                             realisation's frequencies
:mod:`.realisation_bias`     the realisation's misfit beyond its noise (``bias="local"``)
===========================  ================================================================
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from ..._errors import DataError
from ...checks import check_freqs
from ...models.frequency_response import FrequencyResponse
from ...models.statespace import StateSpaceModel
from ...runtime.threads import single_blas_thread
from ..map.posterior import Posterior
from ..realisation.era import realize
from ..realisation.weighting import output_weights, weight_scales, weighted_theta
from ..statistics.window_covariance import overlap_response_covariance, response_directions
from .grid_placement import GRID_PLACEMENTS, placed_grid
from .realisation_bias import local_misfit_bias, misfit_noise

__all__ = [
    "UNCERTAINTY_METHODS",
    "DEFAULT_SAMPLES",
    "model_jacobian",
    "response_points",
    "TangentProjection",
    "response_std",
    "eq9_response_covariance",
    "weighted_parts",
    "column_solve",
    "channel_delta_std",
    "realised_response_uncertainty",
]

#: Draws of the posterior for ``method="sampling"``.
DEFAULT_SAMPLES = 40
#: Most response entries (frequencies x outputs x inputs) of the eq. 9 covariance in ``"delta"``.
MAX_COVARIANCE_ENTRIES = 300
#: For the covariance under overlapping windows (``overlap="exact"``): at most this many
#: frequencies times ``max(q, m)``; the cost grows with its square.  Where they go is
#: :mod:`.grid_placement` (``grid``): placed at the lightly damped modes they reproduce the
#: fit's full grid far better than evenly (``studies/uncertainty/RESULTS.md``).
MAX_OVERLAP_COLUMNS = 72
#: Frequencies per block where a Jacobian over many frequencies is formed.
CHUNK = 256
#: Relative singular value (of the column-normalised Jacobian) below which a direction of
#: ``A, B, C, D`` counts as a similarity direction (no effect on the response).
GAUGE_TOLERANCE = 1e-9


def response_points(freqs_hz: np.ndarray, dt: float | None) -> np.ndarray:
    """``z = exp(j 2 pi f dt)`` (discrete) or ``s = j 2 pi f`` (continuous, ``dt`` None)."""
    f = np.asarray(freqs_hz, dtype=float)
    return 2j * np.pi * f if dt is None else np.exp(2j * np.pi * f * dt)


def model_jacobian(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, points: np.ndarray, feedthrough: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Response ``G = C (xI - A)^-1 B + D`` at ``points`` and its Jacobian in the matrix entries.

    ``dG = C R dA R B + C R dB + dC R B + dD`` with ``R = (xI - A)^-1``.

    Returns
    -------
    G : ndarray of shape (n_points, q, m), complex
    J : ndarray of shape (n_points, q, m, n_params), complex
        Columns: ``vec`` of ``A`` (row-major), ``B``, ``C``, then ``D`` when ``feedthrough``.

    Examples
    --------
    >>> import numpy as np
    >>> G, J = model_jacobian(np.array([[0.5]]), np.array([[1.0]]), np.array([[2.0]]), np.zeros((1, 1)), np.array([1.0]))
    >>> float(G[0, 0, 0].real), J[0, 0, 0].real.tolist()   # G = 2 / (z - 0.5) at z = 1
    (4.0, [8.0, 4.0, 2.0, 1.0])
    """
    n, m, q = A.shape[0], B.shape[1], C.shape[0]
    R = np.linalg.inv(points[:, None, None] * np.eye(n)[None] - A[None])  # (nz, n, n)
    CR = C[None] @ R
    RB = R @ B[None]
    G = CR @ B[None] + D[None]
    nz = points.size
    RBt = RB.transpose(0, 2, 1)  # (nz, m, n)
    JA = (CR[:, :, None, :, None] * RBt[:, None, :, None, :]).reshape(nz, q, m, n * n)
    JB = (CR[:, :, None, :, None] * np.eye(m)[None, None, :, None, :]).reshape(nz, q, m, n * m)
    JC = (np.eye(q)[None, :, None, :, None] * RBt[:, None, :, None, :]).reshape(nz, q, m, q * n)
    parts = [JA, JB, JC]
    if feedthrough:
        parts.append(np.broadcast_to(np.eye(q * m).reshape(1, q, m, q * m), (nz, q, m, q * m)))
    return G, np.concatenate(parts, axis=3)


@dataclasses.dataclass(frozen=True)
class TangentProjection:
    """First-order map of a weighted least-squares fit of a model's response to data on a grid.

    For ``min_x sum ||W^1/2 (G_model(x) - G_data)||^2`` at a minimum, ``dx = M [Re dG; Im dG]``;
    the model's response then moves by ``J(f) dx`` anywhere.  Stored in the reduced form
    ``dx = basis @ phi`` with ``phi = Re(functionals @ vec(dG))``.

    Attributes
    ----------
    functionals : ndarray of shape (r, n_points * q * m), complex
        ``phi = Re(functionals @ vec(dG))``: the data's weighted projection on the ``r``
        identifiable directions.
    basis : ndarray of shape (n_params, r)
        ``dx = basis @ phi``.
    """

    functionals: np.ndarray
    basis: np.ndarray

    @classmethod
    def from_jacobian(cls, J: np.ndarray, weights: np.ndarray, n_gauge: int = 0) -> TangentProjection:
        """From the Jacobian ``J`` (n_points, q, m, n_params) at the fit and the weight of every
        response entry (broadcastable to (n_points, q, m)); at most ``n_params - n_gauge``
        directions are kept (``n_gauge = n^2`` similarity directions of a minimal realisation)."""
        P = J.shape[3]
        sw = np.sqrt(np.broadcast_to(weights, J.shape[:3])).reshape(-1)
        Jw = J.reshape(-1, P) * sw[:, None]
        norms = np.sqrt(np.sum(np.abs(Jw) ** 2, axis=0))
        norms = np.where(norms > 0, norms, 1.0)
        Jn = Jw / norms[None, :]
        # the Gram matrix's eigenpairs are the SVD of the real-stacked [Re Jn; Im Jn] at a seventh
        # of its cost; its precision (eps relative to the largest eigenvalue) is why the kept
        # directions are also capped by the known number of similarity directions
        ev, V = np.linalg.eigh(Jn.real.T @ Jn.real + Jn.imag.T @ Jn.imag)  # Re(Jn^H Jn): two real products
        ev, V = ev[::-1], V[:, ::-1]
        ok = int(np.sum(ev > GAUGE_TOLERANCE**2 * max(float(ev[0]), 1e-300))) if ev.size else 0
        keep = min(ok, max(P - n_gauge, 1))
        s = np.sqrt(ev[:keep])
        Ur = (Jn @ V[:, :keep]) / s[None, :]  # complex (N, keep): Re-stacked left singular vectors
        functionals = np.conj(Ur).T * sw[None, :]  # Re(f @ dG) = Re(Ur)^T Re dG + Im(Ur)^T Im dG
        basis = (V[:, :keep] / s[None, :]) / norms[:, None]
        return cls(functionals, basis)

    def moments(self, cov: np.ndarray, pseudo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Cov(phi)`` (r, r) and ``E[phi conj(dG)^T]`` (r, N) for ``phi = Re(F vec dG)``, from
        ``E[dG dG^H]`` and ``E[dG dG^T]``."""
        F = self.functionals
        Fc, Fp = F @ cov, F @ pseudo
        phi = 0.5 * np.real(Fc @ np.conj(F).T + Fp @ F.T)
        return 0.5 * (phi + phi.T), 0.5 * (Fc + np.conj(Fp))

    def parameter_factor(self, phi_cov: np.ndarray) -> np.ndarray:
        """``L`` with ``L L^T = Cov(dx)`` (clipped at zero eigenvalues) from ``Cov(phi)``
        (:meth:`moments`), shape (n_params, r)."""
        ev, V = np.linalg.eigh(phi_cov)
        return self.basis @ (V * np.sqrt(np.clip(ev, 0.0, None))[None, :])


def response_std(
    abcd: tuple[np.ndarray, ...], factor: np.ndarray, points: np.ndarray, feedthrough: bool = True
) -> np.ndarray:
    """``sqrt(E|dG|^2)`` at ``points`` for parameters with ``Cov(dx) = factor factor^T``, shape
    (n_points, q, m); in blocks of ``CHUNK`` points.

    ``J dx`` for every column of ``factor`` without forming ``J``: ``C R (dA R B + dB) + dC R B
    + dD`` (:func:`model_jacobian`), about a quarter of the flops of ``J @ factor``.
    """
    A, B, C, D = abcd
    n, m, q, r = A.shape[0], B.shape[1], C.shape[0], factor.shape[1]
    LA = factor[: n * n].reshape(n, n, r)  # dA[a, b] per column
    LB = factor[n * n : n * n + n * m].reshape(n, m, r)
    LC = factor[n * n + n * m : n * n + n * m + q * n].reshape(q, n, r)
    LA_f = LA.reshape(n, n * r)  # [a, (b, col)]
    LB_f = LB.reshape(n, m * r)  # [a, (j, col)]
    LC_t = LC.transpose(1, 0, 2).reshape(n, q * r)  # [b, (i, col)]
    out = []
    for lo in range(0, points.size, CHUNK):
        x = points[lo : lo + CHUNK]
        nz = x.size
        R = np.linalg.inv(x[:, None, None] * np.eye(n)[None] - A[None])
        CR = (C[None] @ R).reshape(nz * q, n)  # [(z, i), a]
        RBt = (R @ B[None]).transpose(0, 2, 1)  # (nz, m, n): [z, j, b]
        # (C R dA) (R B) + C R dB: the real factor times the complex C R first (two real products
        # each), then the small product with R B per point, no regrouping of a large array
        T = (CR.real @ LA_f + 1j * (CR.imag @ LA_f)).reshape(nz, q, n, r)
        dG = np.matmul(RBt[:, None], T)  # (nz, q, m, r)
        dG += (CR.real @ LB_f + 1j * (CR.imag @ LB_f)).reshape(nz, q, m, r)
        RBf = RBt.reshape(nz * m, n)
        dG += (RBf.real @ LC_t + 1j * (RBf.imag @ LC_t)).reshape(nz, m, q, r).transpose(0, 2, 1, 3)
        if feedthrough:
            dG += factor[n * n + n * m + q * n :].reshape(q, m, r)[None]
        out.append(np.sqrt(np.sum(dG.real**2 + dG.imag**2, axis=3)))
    return np.concatenate(out, axis=0)


def eq9_response_covariance(
    theta: np.ndarray,
    column_cov: np.ndarray,
    noise_cov: np.ndarray,
    horizon: int,
    n_inputs: int,
    n_outputs: int,
    freqs: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The eq. 9 response on a grid and the covariance of its error across the whole grid.

    ``dG_k = L_k^+ dtheta V_k`` (``theta_response_std``) with ``Cov(vec theta) = P (x) Sigma``
    gives ``E[dG_k(i,j) conj(dG_l(i',j'))] = (L_k^+ Sigma L_l^+H)_(ii') (V_k^T P conj V_l)_(jj')``
    and the pseudo-covariance (no conjugate) likewise: ``theta`` is real, so both are needed.

    Returns
    -------
    G : ndarray of shape (n_freqs, q, m), complex
    cov, pseudo : ndarrays of shape (n_freqs q m, n_freqs q m), complex (``vec`` in (k, i, j) order)
    """
    p, m, q = horizon, n_inputs, n_outputs
    G, Lp, V = response_directions(theta, p, m, q, freqs, dt)
    nz = G.shape[0]
    PV = column_cov @ V.real + 1j * (column_cov @ V.imag)  # a real matrix: half the flops of complex
    A_c = (V.T @ np.conj(PV)).reshape(nz, m, nz, m)
    A_p = (V.T @ PV).reshape(nz, m, nz, m)
    L2 = Lp.reshape(nz * q, p * q)
    LS = L2 @ noise_cov
    B_c = (LS @ np.conj(L2).T).reshape(nz, q, nz, q)
    B_p = (LS @ L2.T).reshape(nz, q, nz, q)
    N = nz * q * m
    cov = (B_c[:, :, None, :, :, None] * A_c[:, None, :, :, None, :]).reshape(N, N)
    pseudo = (B_p[:, :, None, :, :, None] * A_p[:, None, :, :, None, :]).reshape(N, N)
    return G, cov, pseudo


def covariance_grid(
    band: tuple[float, float], n_frequencies: int, n_entries: int, cap: int = MAX_COVARIANCE_ENTRIES
) -> np.ndarray:
    """The realisation's grid (``n_frequencies`` evenly over ``band``), every ``s``-th point kept so
    that at most ``cap`` response entries enter the covariance.

    The realisation's least-squares fit on an even grid approximates an integral over the band;
    a coarser even grid approximates the same integral as long as it resolves the response, and
    the covariance costs ``(n_freqs q m)^2`` memory and ``r (n_freqs q m)^2`` work.
    """
    stride = max(1, int(np.ceil(n_frequencies * n_entries / cap)))
    return np.linspace(band[0], band[1], n_frequencies)[::stride]


def weighted_parts(post: Posterior) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``theta`` and its covariance factors for the noise-whitened outputs the realisation fits
    (``p P`` for the window overlap, as ``response_bands``), and the output weights."""
    p, m, q = post.horizon, post.n_inputs, post.n_outputs
    w = output_weights(post)
    wp, c = weight_scales(w, p, m)
    theta_w = weighted_theta(post.theta, w, p, m, q)
    return theta_w, post.covariance * p * np.outer(c, c), post.noise_cov * np.outer(wp, wp), w


def column_solve(post: Posterior) -> Callable[[np.ndarray], np.ndarray]:
    """``V -> P V`` in the coordinates of :func:`weighted_parts` (without its factor ``p``): a
    solve with the posterior information instead of its inverse (``Posterior.covariance``), the
    same definiteness test (Cholesky) and the same fallback (the pseudo-inverse)."""
    _, c = weight_scales(output_weights(post), post.horizon, post.n_inputs)
    info = post.information
    try:
        np.linalg.cholesky(info)
        return lambda V: c[:, None] * _real_apply(lambda X: np.linalg.solve(info, X), c[:, None] * V)
    except np.linalg.LinAlgError:
        pinv = np.linalg.pinv(info, hermitian=True)
        return lambda V: c[:, None] * _real_apply(lambda X: pinv @ X, c[:, None] * V)


def _real_apply(op: Callable[[np.ndarray], np.ndarray], V: np.ndarray) -> np.ndarray:
    """``op(V)`` for a linear ``op`` with a real matrix and a complex ``V``: one real call on
    ``[Re V, Im V]`` (a complex right-hand side would make numpy factor the matrix as complex)."""
    if not np.iscomplexobj(V):
        return op(V)
    k = V.shape[1]
    X = op(np.hstack([V.real, V.imag]))
    return X[:, :k] + 1j * X[:, k:]


def _fit_coordinates(model: StateSpaceModel, su: np.ndarray, sy: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, ...]:
    """The channel's model in the coordinates of its realisation: unit-RMS channels, outputs times ``w``."""
    ow = (w / sy)[:, None]
    return model.A, model.B * su[None, :], model.C * ow, model.D * su[None, :] * ow


def channel_delta_std(
    ch, estimator, freqs: np.ndarray, dt: float, overlap: str = "auto", bias: str = "local", grid: str = "modes"
) -> np.ndarray:
    """``"delta"``: std of the realised response of one channel fit at ``freqs`` (data units).

    ``overlap``: ``"exact"`` takes the eq. 9 covariance under overlapping windows
    (:mod:`~stageid.subspace.statistics.window_covariance`, from the lag statistics the fit kept); ``"inflate"`` the
    matrix-normal ``p P (x) Sigma`` (windows counted as independent, ``P`` times ``p`` for their
    overlap: a rough allowance); ``"auto"`` the first when the fit kept its lag statistics (not
    after ``update``, with forgetting, or on records shorter than ``8 p``).  ``bias``: ``"local"``
    adds the realisation's misfit beyond its noise (:mod:`.realisation_bias`), ``"none"`` not.
    ``grid`` (``"exact"`` only): where the covariance is formed, ``"modes"`` (more points at the
    realised model's lightly damped modes) or ``"even"`` (:mod:`.grid_placement`).
    """
    post = ch.scaled_posterior
    p, m, q = post.horizon, post.n_inputs, post.n_outputs
    su, sy = ch.scales if ch.scales is not None else (np.ones(m), np.ones(q))
    exact = overlap == "exact" or (overlap == "auto" and ch.window_lags is not None)
    if exact and ch.window_lags is None:
        raise DataError("`overlap='exact'` needs the fit's lag statistics; this fit has none (update or forgetting).")
    if exact:
        w = output_weights(post)
        theta_w = weighted_theta(post.theta, w, p, m, q)
        budget = MAX_OVERLAP_COLUMNS // max(q, m)
        f_grid, quad = placed_grid(ch.band, int(estimator.n_frequencies), budget, ch.model.A, dt, grid)
        stats = ch.window_lags.weighted(np.concatenate([np.ones(m), w]))  # z = [u; w y], the realisation's outputs
        solve = column_solve(post)
        G9, cov, pseudo = overlap_response_covariance(theta_w, solve, stats, post.n_windows, p, m, q, f_grid, dt)
    else:
        theta_w, col_cov, noise_cov, w = weighted_parts(post)
        f_grid = covariance_grid(ch.band, int(estimator.n_frequencies), q * m)
        quad = np.ones(f_grid.size)
        G9, cov, pseudo = eq9_response_covariance(theta_w, col_cov, noise_cov, p, m, q, f_grid, dt)
    scale = np.max(np.abs(G9), axis=(0, 1))
    scale = np.where(scale > 0, scale, 1.0)
    A, B, C, D = _fit_coordinates(ch.model, su, sy, w)
    feed = bool(estimator.feedthrough)
    Gm, J = model_jacobian(A, B, C, D, response_points(f_grid, dt), feed)
    # the fit's weight per column, times the share of the fit's frequencies each point stands for
    proj = TangentProjection.from_jacobian(J, quad[:, None, None] / scale[None, None, :] ** 2, n_gauge=A.shape[0] ** 2)
    phi_cov, phi_dG = proj.moments(cov, pseudo)
    std = response_std((A, B, C, D), proj.parameter_factor(phi_cov), response_points(freqs, dt), feed)
    if bias == "local":
        K = J.reshape(-1, J.shape[3]) @ proj.basis
        noise = misfit_noise(K, phi_cov, phi_dG, np.real(np.diag(cov))).reshape(Gm.shape)
        uneven = None if np.all(quad == quad[0]) else quad
        b2 = local_misfit_bias(f_grid, np.abs(Gm - G9) ** 2, noise, Gm, freqs, uneven)
        Gf = model_response(StateSpaceModel(A, B, C, D, dt), freqs)
        std = np.sqrt(std**2 + b2 * np.abs(Gf) ** 2)
    return std * (sy / w)[None, :, None] / su[None, None, :]


def channel_sampling_std(ch, estimator, freqs: np.ndarray, dt: float, n_samples: int, rng) -> np.ndarray:
    """``"sampling"``: draws of ``theta`` from the posterior (``p P (x) Sigma``), each realised by
    the fit's route and order; the RMS distance of their responses from the identified one."""
    post = ch.scaled_posterior
    p, m, q = post.horizon, post.n_inputs, post.n_outputs
    su, sy = ch.scales if ch.scales is not None else (np.ones(m), np.ones(q))
    row = _psd_factor(post.noise_cov)
    col = _psd_factor(post.covariance * p)
    grid = np.linspace(ch.band[0], ch.band[1], int(estimator.n_frequencies))
    settings = {"realization": estimator.realization, "feedthrough": estimator.feedthrough, "refine": estimator.refine}
    G0 = ch.model.frequency_response(freqs)
    acc = np.zeros(G0.shape)
    for _ in range(n_samples):
        theta = post.theta + row @ rng.standard_normal(post.theta.shape) @ col.T
        model, _ = realize(dataclasses.replace(post, theta=theta), ch.order, grid, dt, **settings)
        scaled = StateSpaceModel(model.A, model.B / su[None, :], model.C * sy[:, None], model.D * sy[:, None] / su, dt)
        acc += np.abs(scaled.frequency_response(freqs) - G0) ** 2
    return np.sqrt(acc / n_samples)


def _psd_factor(M: np.ndarray) -> np.ndarray:
    ev, V = np.linalg.eigh(0.5 * (M + M.T))
    return V * np.sqrt(np.clip(ev, 0.0, None))[None, :]


#: ``method`` of :func:`realised_response_uncertainty` -> what it does (``"auto"`` picks).
UNCERTAINTY_METHODS = ("auto", "delta", "sampling")
#: ``overlap`` of :func:`realised_response_uncertainty` (:func:`channel_delta_std`).
OVERLAP_RULES = ("auto", "exact", "inflate")
#: ``bias`` of :func:`realised_response_uncertainty` (:mod:`.realisation_bias`).
BIAS_RULES = ("local", "none")


@single_blas_thread
def realised_response_uncertainty(
    result,
    freqs_hz: Sequence[float] | np.ndarray,
    method: str = "auto",
    n_samples: int = DEFAULT_SAMPLES,
    seed: int = 0,
    overlap: str = "auto",
    bias: str = "local",
    grid: str = "modes",
) -> FrequencyResponse:
    """The realised model's response with ``std = sqrt(E|G_est - G|^2)`` (see the module docstring).

    Parameters
    ----------
    result : HankelMAPResult
    freqs_hz : array_like of shape (n_freqs,)
        Frequencies in Hz within ``[0, 1 / (2 dt)]``.
    method : {"auto", "delta", "sampling"}
        ``auto``: ``delta`` for the refined frequency route, ``sampling`` otherwise.
    n_samples, seed : int
        Draws and seed of ``sampling`` (whose posterior is the matrix-normal one with ``p P``).
    overlap : {"auto", "exact", "inflate"}
        The eq. 9 covariance of ``delta`` (:func:`channel_delta_std`).
    bias : {"local", "none"}
        ``delta`` only: ``local`` adds the realisation's misfit beyond its noise where it is
        significant (:mod:`.realisation_bias`); ``none`` the propagated scatter alone.
    grid : {"modes", "even"}
        ``delta`` with the exact covariance: its frequencies placed at the realised model's
        lightly damped modes and evenly between, or evenly (:mod:`.grid_placement`).

    Raises
    ------
    DataError
        Frequencies that are not finite, negative or above Nyquist; an unknown ``method`` or
        ``overlap`` or ``bias``; ``overlap="exact"`` for a fit without lag statistics.
    """
    f = check_freqs(freqs_hz, result.model.dt)
    if method not in UNCERTAINTY_METHODS:
        raise DataError(f"`method` must be one of {', '.join(UNCERTAINTY_METHODS)}; got {method!r}.")
    if overlap not in OVERLAP_RULES:
        raise DataError(f"`overlap` must be one of {', '.join(OVERLAP_RULES)}; got {overlap!r}.")
    if bias not in BIAS_RULES:
        raise DataError(f"`bias` must be one of {', '.join(BIAS_RULES)}; got {bias!r}.")
    if grid not in GRID_PLACEMENTS:
        raise DataError(f"`grid` must be one of {', '.join(GRID_PLACEMENTS)}; got {grid!r}.")
    est = result.estimator
    if method == "auto":
        method = "delta" if est.realization == "frequency" and est.refine else "sampling"
    dt = result.model.dt
    # only the draws need a generator: numpy.random's import is a tenth of a command-line run's uncertainty
    rng = np.random.default_rng(seed) if method == "sampling" else None
    stds = []
    for ch in result.channels:
        if method == "delta":
            stds.append(channel_delta_std(ch, est, f, dt, overlap, bias, grid))
        else:
            stds.append(channel_sampling_std(ch, est, f, dt, int(n_samples), rng))
    model = result.model
    return FrequencyResponse(
        f, model_response(model, f), np.concatenate(stds, axis=2), None, model.inputs, model.outputs
    )


def model_response(model: StateSpaceModel, freqs_hz: np.ndarray) -> np.ndarray:
    """``C (xI - A)^-1 B + D`` at ``freqs_hz`` by numpy's batched solve, shape (n_freqs, q, m):
    ``model.frequency_response`` imports scipy.linalg, which costs a command-line run more than
    the uncertainty itself."""
    x = response_points(freqs_hz, model.dt)
    n = model.n_states
    if n == 0:
        return np.broadcast_to(model.D, (x.size,) + model.D.shape).astype(complex)
    R = np.linalg.solve(
        x[:, None, None] * np.eye(n)[None] - model.A[None], np.broadcast_to(model.B, (x.size,) + model.B.shape)
    )
    return model.C[None] @ R + model.D[None]
