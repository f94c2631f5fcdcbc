"""HankelMAP weighs the outputs by their noise, not by their RMS (realisation and selection).

The P-558 chirp on Rx: rx is 47 urad RMS with 0.1 urad noise, the coupling outputs are 8 nm
(1 nm noise) and 0.12 urad (0.1 urad noise).  With every output scaled to unit RMS and
weighted alike (commit ba08bf8) the order-4 Rx sub-model had a 2 % error on its own diagonal
at p = 25 and 0.9-1.4 % with the automatic horizon (p = 8 was chosen by the noisy outputs).
"""

import dataclasses

import numpy as np
import pytest

from _subspace_systems import band_limited, record
from stageid.data import Experiment
from stageid.models import StateSpaceModel
from stageid.plants import piezo_stage as ps
from stageid.subspace import HankelMAP
from stageid.subspace.realisation.weighting import NOISE_STD_FLOOR, noise_weights, output_weights

F = np.linspace(1.0, 100.0, 1000)


def _rx_record(seed: int) -> Experiment:
    return ps.EXPERIMENTS["chirp-rx"](seed).select(inputs=["Rx"])


def _errors(model: StateSpaceModel) -> np.ndarray:
    """Largest error over 1-100 Hz of each output, relative to that output's own peak gain."""
    Gt = ps.model().frequency_response(F)[:, :, 1]
    return np.abs(model.frequency_response(F)[:, :, 0] - Gt).max(axis=0) / np.abs(Gt).max(axis=0)


def test_noisy_coupling_outputs_do_not_spoil_the_realisation_of_the_driven_output():
    # horizon and order given: only the realisation's weighting is at work
    # (unit-RMS weighting: rx 2.0 %, z 4.7 %; noise weighting: 0.1 %, 0.2 %)
    res = HankelMAP(horizon=25, order=4).fit(_rx_record(0))
    err = _errors(res.model)
    assert err[1] < 0.005
    assert err[0] < 0.01  # the z coupling (SNR ~8) gains too


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_coupling_outputs_do_not_choose_the_horizon(seed):
    # unit-RMS weighting: p = 8 or 12 and rx errors of 0.9-1.4 %; now p = 40 and <= 0.02 %
    res = HankelMAP(order=4).fit(_rx_record(seed))
    assert res.horizon >= 20
    assert _errors(res.model)[1] < 0.002


def test_noise_weighting_does_not_depend_on_the_units():
    # outputs of very different SNR in other units (z in nm instead of um, rx in rad instead
    # of urad), automatic horizon: the same model in the new units
    e = _rx_record(1)
    ref = HankelMAP(order=4).fit(e)
    k = np.array([1e3, 1e-6, 1.0])
    res = HankelMAP(order=4).fit(Experiment(e.u * 1e-3, e.y * k, e.dt, e.input_names, e.output_names))
    assert res.horizon == ref.horizon
    G_ref = ref.model.frequency_response(F)
    G = res.model.frequency_response(F) * 1e-3 / k[None, :, None]
    np.testing.assert_allclose(G, G_ref, rtol=1e-6, atol=1e-9 * np.abs(G_ref).max())
    np.testing.assert_allclose(
        np.sort_complex(res.model.poles()), np.sort_complex(ref.model.poles()), rtol=1e-6, atol=1e-9
    )


def test_equal_relative_noise_and_noise_free_records_weigh_the_outputs_alike():
    g = ps.model()
    u = band_limited(20000, 3, g.dt, 4) * np.array([10.0, 100.0, 100.0])
    # 1 % noise on every output (the benchmark's case): the unit-RMS weighting within a few %
    # (measured 0.989-1)
    res = HankelMAP(horizon=40, order=15).fit(record(g, u, 0.01, 4))
    w = output_weights(res.channels[0].scaled_posterior)
    assert w.max() == 1.0 and w.min() > 0.9
    # noise-free: every noise std (residual 0.7-3.3e-4 of the RMS) at the floor of 1e-3 of the
    # RMS over the windows, so the weights are those of unit RMS (measured 0.9983-1)
    res = HankelMAP(horizon=40, order=15).fit(Experiment(u, g.simulate(u), g.dt))
    np.testing.assert_allclose(output_weights(res.channels[0].scaled_posterior), 1.0, rtol=5e-3)
    # and with a noisy coupling output (rx at 30 % noise) the clean outputs weigh more
    res = HankelMAP(horizon=40, order=15).fit(_noisy(g, u, [0.01, 0.3, 0.01]))
    w = output_weights(res.channels[0].scaled_posterior)
    assert w[1] < 0.1 * min(w[0], w[2])


def _noisy(g: StateSpaceModel, u: np.ndarray, rel: list[float]) -> Experiment:
    y = g.simulate(u)
    y = y + np.asarray(rel) * y.std(axis=0) * np.random.default_rng(9).standard_normal(y.shape)
    return Experiment(u, y, g.dt, g.inputs, g.outputs)


def test_noise_weights_by_hand():
    # std_i = max(noise std_i, NOISE_STD_FLOOR * RMS_i), w = (1 / std) / max(1 / std): two
    # noise-free outputs of RMS 2 and 10 (floored) and a noisy one of std 0.2
    w = noise_weights(np.array([0.0, 0.0, 0.04]), np.array([4.0, 100.0, 1.0]))
    std = np.array([NOISE_STD_FLOOR * 2, NOISE_STD_FLOOR * 10, 0.2])
    np.testing.assert_allclose(w, (1 / std) / np.max(1 / std), rtol=1e-12)  # [1, 0.2, 0.01]
    # an output that is zero and noise-free takes the weight of the noisiest (it does not matter)
    np.testing.assert_allclose(noise_weights(np.array([0.0, 0.01]), np.array([0.0, 1.0])), [1.0, 1.0], rtol=1e-12)
    np.testing.assert_array_equal(noise_weights(np.zeros(2), np.zeros(2)), [1.0, 1.0])  # nothing to go on


def test_output_weights_floor_uses_the_records_rms():
    # output_weights reads only the noise covariance, the data sums and the window count: a
    # posterior built by hand (p = 2 block rows, q = 2 outputs) with output 0 noise-free at RMS 2
    # and output 1 at noise std 0.1, RMS 1
    from stageid.subspace.map.posterior import Posterior

    n, p, q = 500.0, 2, 2
    YY = np.diag(n * np.array([4.0, 1.0, 4.0, 1.0]))
    post = Posterior(
        information=np.eye(1),
        moment=np.zeros((p * q, 1)),
        theta=np.zeros((p * q, 1)),
        noise_cov=np.diag([0.0, 0.01, 0.0, 0.01]),
        n_windows=n,
        horizon=p,
        n_inputs=1,
        n_outputs=q,
        residual=np.zeros((p * q, p * q)),
        data_sums=(np.eye(1), np.zeros((p * q, 1)), YY),
    )
    std = np.array([NOISE_STD_FLOOR * 2.0, 0.1])  # the floor scales with the output's RMS (2, not 1)
    np.testing.assert_allclose(output_weights(post), (1 / std) / np.max(1 / std), rtol=1e-12)
    # no data sums (or no windows): the channels' own unit scale
    std1 = np.array([NOISE_STD_FLOOR, 0.1])
    for bare in (dataclasses.replace(post, data_sums=()), dataclasses.replace(post, n_windows=0.0)):
        np.testing.assert_allclose(output_weights(bare), (1 / std1) / np.max(1 / std1), rtol=1e-12)


def test_training_weights_estimate_the_noise_and_floor_the_clean_output():
    # y0 = 3-tap FIR of u (noise-free, inside the horizon: its residual vanishes, the floor
    # applies), y1 = another FIR plus white noise of std 0.5; theta is the least-squares fit
    from stageid.subspace.realisation.weighting import training_weights
    from stageid.subspace.statistics.hankel_toeplitz import window_statistics

    rng = np.random.default_rng(7)
    n, p = 4000, 5
    u = rng.standard_normal((n, 1))
    y0 = np.convolve(u[:, 0], [3.0, -1.0, 0.5])[:n]
    y1 = np.convolve(u[:, 0], [0.2, 0.4])[:n] + 0.5 * rng.standard_normal(n)
    stats = window_statistics(u, np.column_stack([y0, y1]), p)
    XX, YX, _ = stats.blocks()
    theta = np.linalg.solve(XX, YX.T).T
    w = training_weights(theta, stats)
    std0 = NOISE_STD_FLOOR * np.sqrt(np.mean(y0**2))  # the floor, at the clean output's RMS
    assert w[0] == 1.0
    # the noise std estimated with n_windows - d degrees of freedom: 4000 windows give ~1.1 %
    # standard error, 5 % is > 4 of them
    np.testing.assert_allclose(w[1], std0 / 0.5, rtol=0.05)
