"""Validation of a closed-loop identification (Shakir & Kim, Fig. 4, 7, 8) and the naive baseline.

=========================  ==================================================================
``simulate_closed_loop``   sampled loop ``u = M (r - y_m)``, ``y = G u``, ``y_m = y + n`` with
                           output noise at a given SNR (the experiments of sec. 3.1)
``empirical_transfer``     FFT ratio ``Y(f) / R(f)`` of one experiment (thin lines of Fig. 4b)
``reclose_loop``           the identified plant closed with the known controller, driven by
                           the recorded references (Fig. 8)
``direct_identification``  the baseline a user tries first: ARX from ``u`` to ``y`` as if the
                           loop were open; biased because ``u`` is correlated with the noise
=========================  ==================================================================
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import DataError, ModelError
from ..data.sampling import PERIOD_RTOL, same_period, seconds
from ..models import StateSpaceModel, TransferMatrix, feedback
from .regression import lstsq, shifted

__all__ = ["simulate_closed_loop", "empirical_transfer", "reclose_loop", "direct_identification", "controller_residual"]


def _discrete_plant(plant: StateSpaceModel | TransferMatrix, dt: float) -> StateSpaceModel:
    g = plant.to_statespace(minimal=False) if isinstance(plant, TransferMatrix) else plant
    if g.dt is None:
        return g.c2d(dt, "zoh")
    if not same_period(g.dt, dt):
        raise ModelError(
            f"the plant's sample time {seconds(g.dt)} s differs from {seconds(dt)} s (tolerance {PERIOD_RTOL:g} relative)."
        )
    return g


def simulate_closed_loop(
    plant: StateSpaceModel | TransferMatrix,
    controller: StateSpaceModel | TransferMatrix,
    references: np.ndarray,
    dt: float,
    snr_db: float | None = None,
    seed: int = 0,
    noise_reference: str = "channel",
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate the sampled loop with white output noise.

    Parameters
    ----------
    plant : continuous (ZOH-sampled at ``dt``) or discrete model, m inputs, p outputs
    controller : discrete model at ``dt`` (or continuous: Tustin at ``dt``), p -> m
    references : ndarray of shape (n_samples, p)
    dt : float
    snr_db : float, optional
        Output signal-to-noise ratio; ``None`` for no noise.
    seed : int
        Seed of ``np.random.default_rng``.
    noise_reference : {"channel", "excited"}
        "channel": each output's noise std is ``10^(-snr/20)`` times that output's own
        noise-free RMS; "excited": times the RMS of the largest output (harder for the
        coupling channels).

    Returns
    -------
    (y_measured, u) : ndarrays of shape (n_samples, p) and (n_samples, m)

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.models import StateSpaceModel
    >>> G = StateSpaceModel([[1.0]], [[1.0]], [[1.0]], [[0.0]])          # 1 / (s - 1)
    >>> K = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[10.0]], 0.01)
    >>> y, u = simulate_closed_loop(G, K, np.ones((500, 1)), 0.01)
    >>> round(float(y[-1, 0]), 3)                                         # 10 / (10 - 1)
    1.111
    """
    r = np.array(references, dtype=float)
    if r.ndim == 1:
        r = r[:, None]
    G = _discrete_plant(plant, dt)
    K = controller.to_statespace(minimal=False) if isinstance(controller, TransferMatrix) else controller
    if K.dt is None:
        K = K.c2d(dt, "tustin")
    if r.shape[1] != G.n_outputs:
        raise DataError(f"references must have shape (n_samples, {G.n_outputs}); got {r.shape}.")
    loop = feedback(G, K, noise_inputs=True)
    p = G.n_outputs
    clean = loop.simulate(np.hstack([r, np.zeros_like(r)]))
    if snr_db is None:
        return clean[:, :p], clean[:, p:]
    rng = np.random.default_rng(seed)
    rms = np.sqrt(np.mean((clean[:, :p] - clean[:, :p].mean(axis=0)) ** 2, axis=0))
    if noise_reference == "excited":
        rms = np.full(p, rms.max())
    elif noise_reference != "channel":
        raise DataError(f"`noise_reference` must be 'channel' or 'excited'; got {noise_reference!r}.")
    n = rng.standard_normal(r.shape) * rms * 10.0 ** (-snr_db / 20.0)
    out = loop.simulate(np.hstack([r, n]))
    return out[:, :p] + n, out[:, p:]


def empirical_transfer(
    reference: np.ndarray,
    outputs: np.ndarray,
    dt: float,
    band: tuple[float, float] | None = None,
    min_relative_power: float = 1e-3,
) -> tuple[np.ndarray, np.ndarray]:
    """Empirical transfer function ``Y(f) / R(f)`` from the FFTs of one experiment.

    Parameters
    ----------
    reference : ndarray of shape (n_samples,)
    outputs : ndarray of shape (n_samples, n_outputs)
    dt : float
    band : (float, float), optional
        Keep only FFT lines inside the band.
    min_relative_power : float
        Keep only lines where ``|R(f)|^2`` exceeds this fraction of its mean (no division
        by unexcited lines).

    Returns
    -------
    (freqs_hz, etfe) : ndarrays of shape (n_lines,) and (n_lines, n_outputs)
    """
    r = np.asarray(reference, dtype=float).reshape(-1)
    y = np.asarray(outputs, dtype=float)
    y = y[:, None] if y.ndim == 1 else y
    if y.shape[0] != r.size:
        raise DataError(f"reference and outputs must have the same number of samples; got {r.size} and {y.shape[0]}.")
    R = np.fft.rfft(r - r[0])
    Y = np.fft.rfft(y - y[0], axis=0)
    f = np.fft.rfftfreq(r.size, dt)
    power = np.abs(R) ** 2
    keep = power > min_relative_power * power.mean()
    if band is not None:
        keep &= (f >= band[0]) & (f <= band[1])
    return f[keep], Y[keep] / R[keep, None]


def reclose_loop(
    plant: StateSpaceModel | TransferMatrix,
    controller: StateSpaceModel | TransferMatrix,
    references: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Outputs and plant inputs of the identified plant closed with the known controller (Fig. 8).

    Returns
    -------
    (y, u) : ndarrays of shape (n_samples, p) and (n_samples, m); noise-free.
    """
    return simulate_closed_loop(plant, controller, references, dt, snr_db=None)


def controller_residual(
    controller: StateSpaceModel | TransferMatrix,
    references: np.ndarray,
    outputs: np.ndarray,
    plant_inputs: np.ndarray,
    dt: float,
) -> np.ndarray:
    """``||u - M (r - y)|| / ||u||`` per plant input: ~0 when the loop was closed by ``M``.

    Parameters
    ----------
    references, outputs : ndarrays of shape (n_samples, p)
    plant_inputs : ndarray of shape (n_samples, m)

    Returns
    -------
    ndarray of shape (m,)
    """
    K = controller.to_statespace(minimal=False) if isinstance(controller, TransferMatrix) else controller
    if K.dt is None:
        K = K.c2d(dt, "tustin")
    e = np.asarray(references, float) - np.asarray(outputs, float)
    u = np.asarray(plant_inputs, float)
    if e.shape[1] != K.n_inputs or u.shape[1] != K.n_outputs:
        raise DataError(
            f"the controller maps {K.n_inputs} errors to {K.n_outputs} inputs; got {e.shape[1]} references/outputs and {u.shape[1]} plant inputs."
        )
    # the controller is simulated from rest: the records are expected to start at rest
    u_hat = K.simulate(e)
    return np.linalg.norm(u - u_hat, axis=0) / np.maximum(np.linalg.norm(u, axis=0), 1e-300)


def direct_identification(
    plant_inputs: Sequence[np.ndarray],
    outputs: Sequence[np.ndarray],
    dt: float,
    order: int = 6,
    freqs_hz: np.ndarray | None = None,
) -> np.ndarray:
    """Naive open-loop ARX from the plant inputs to the outputs, ignoring the feedback.

    Each output gets a MISO ARX model ``A_i y_i = sum_j B_ij u_j + e`` of ``order`` fitted on
    all records; under feedback the input is correlated with the output noise and the
    estimate is biased (Forssell & Ljung 1999).

    Parameters
    ----------
    plant_inputs, outputs : sequences of ndarrays (n_samples, m) and (n_samples, p), one per record
    dt : float
    order : int
    freqs_hz : ndarray, optional
        Where to evaluate the response (default 200 log-spaced lines, 1 Hz to 0.4 fs).

    Returns
    -------
    ndarray of shape (n_freqs, p, m): the frequency response of the direct estimate.
    """
    f = np.geomspace(1.0, 0.4 / dt, 200) if freqs_hz is None else np.asarray(freqs_hz, float)
    U = [np.asarray(u, float) for u in plant_inputs]
    Y = [np.asarray(y, float) for y in outputs]
    m, p = U[0].shape[1], Y[0].shape[1]
    q = np.exp(-2j * np.pi * f * dt)
    out = np.zeros((f.size, p, m), dtype=complex)
    for i in range(p):
        rows, rhs = [], []
        for u, y in zip(U, Y):
            cols = [-shifted(y[:, i] - y[0, i], order, 1)] + [shifted(u[:, j] - u[0, j], order, 1) for j in range(m)]
            rows.append(np.hstack(cols))
            rhs.append(y[:, i] - y[0, i])
        th = lstsq(np.vstack(rows), np.concatenate(rhs), "direct ARX", strict=False)
        A = np.concatenate([[1.0], th[:order]])
        den = np.polynomial.polynomial.polyval(q, A)
        for j in range(m):
            b = np.concatenate([[0.0], th[order * (1 + j) : order * (2 + j)]])
            out[:, i, j] = np.polynomial.polynomial.polyval(q, b) / den
    return out
