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
``__init__`` (here)          ``realised_response_uncertainty``: the delta method or draws,
                             per channel
:mod:`.tangent`              the realised model's response, Jacobian and similarity
                             directions; the response std of a parameter covariance
:mod:`.eq9_covariance`       the covariance of the eq. 9 response across a grid
:mod:`.grid_placement`       where the realised model's covariance is formed: a few of the
                             realisation's frequencies
:mod:`.realisation_bias`     the realisation's misfit beyond its noise (``bias="local"``)
===========================  ================================================================
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..._errors import DataError
from ...checks import check_freqs
from ...models.frequency_response import FrequencyResponse
from ...models.statespace import StateSpaceModel
from ...runtime.threads import single_blas_thread
from ..realisation.era import realize
from ..realisation.weighting import output_weights, weighted_theta
from ..statistics.window_covariance import overlap_response_covariance
from .eq9_covariance import (
    MAX_COVARIANCE_ENTRIES,
    column_solve,
    covariance_grid,
    eq9_response_covariance,
    weighted_parts,
)
from .grid_placement import GRID_PLACEMENTS, placed_grid
from .realisation_bias import local_misfit_bias, misfit_noise
from .tangent import (
    CHUNK,
    GAUGE_TOLERANCE,
    TangentProjection,
    model_jacobian,
    model_response,
    response_points,
    response_std,
)

__all__ = [
    "UNCERTAINTY_METHODS",
    "DEFAULT_SAMPLES",
    "CHUNK",
    "GAUGE_TOLERANCE",
    "MAX_COVARIANCE_ENTRIES",
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
#: For the covariance under overlapping windows (``overlap="exact"``): at most this many
#: frequencies times ``max(q, m)``; the cost grows with its square.  Where they go is
#: :mod:`.grid_placement` (``grid``): placed at the lightly damped modes they reproduce the
#: fit's full grid far better than evenly (``studies/uncertainty/RESULTS.md``).
MAX_OVERLAP_COLUMNS = 72


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
        spread, w = weighted_parts(post)
        f_grid = covariance_grid(ch.band, int(estimator.n_frequencies), q * m)
        quad = np.ones(f_grid.size)
        G9, cov, pseudo = eq9_response_covariance(spread, f_grid, dt)
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
