"""The P-558.TCD reference of Cao & Chen (2013) eq. 23-25."""

import numpy as np
import pytest

from stageid.plants import piezo_stage as ps
from stageid.plants import plant_module


def test_structure_and_names():
    g = ps.model()
    assert g.n_states == 15 and g.dt == 0.002
    assert g.inputs == ("Z", "Rx", "Ry") and g.outputs == ("z", "rx", "ry")
    assert np.all(g.D == 0)
    assert plant_module("p558") is ps
    # eq. 20-22: block-diagonal A and B, C side by side
    assert np.all(g.A[:7, 7:] == 0) and np.all(g.B[:7, 1:] == 0) and np.all(g.B[7:11, [0, 2]] == 0)


def test_poles_and_dc_gains_computed_from_the_paper():
    # eigenvalues of A1 (eq. 23), A2 (eq. 24) and A3 (eq. 25), computed once from the printed
    # matrices with numpy (rounded to 4 digits); the tolerance covers that rounding
    expected = [
        0.538 + 0.4018j,
        0.538 - 0.4018j,
        0.7573,
        0.8199 + 0.097j,
        0.8199 - 0.097j,
        0.8888,
        0.9732,
        0.7821 + 0.2093j,
        0.7821 - 0.2093j,
        0.9184 + 0.0117j,
        0.9184 - 0.0117j,
        0.7811 + 0.2183j,
        0.7811 - 0.2183j,
        0.9305 + 0.0126j,
        0.9305 - 0.0126j,
    ]
    got = np.sort_complex(ps.model().poles())
    np.testing.assert_allclose(got, np.sort_complex(np.array(expected)), atol=6e-5)
    dc = ps.model().dc_gain()
    # diagonal DC gains near 1 (position-controlled stage), computed C (I - A)^-1 B
    np.testing.assert_allclose(np.diag(dc), [0.99133, 1.01455, 0.93655], atol=1e-4)
    assert abs(dc[1, 0]) < 0.002 and abs(dc[2, 1]) < 0.02


def test_channel_models_stack_to_the_mimo_model():
    subs = ps.channel_models()
    assert [s.n_states for s in subs] == [7, 4, 4]
    f = np.linspace(1, 100, 20)
    G = ps.model().frequency_response(f)
    for j, s in enumerate(subs):
        np.testing.assert_allclose(s.frequency_response(f)[:, :, 0], G[:, :, j], atol=1e-12)


def test_experiments_are_seeded_records_with_noise():
    for name in ("chirp-z", "prbs", "sine-5hz-rx", "combined"):
        exp = ps.EXPERIMENTS[name](0)
        assert exp.dt == 0.002 and exp.input_names == ps.INPUTS and exp.output_names == ps.OUTPUTS
    a, b, c = ps.EXPERIMENTS["chirp-rx"](0), ps.EXPERIMENTS["chirp-rx"](0), ps.EXPERIMENTS["chirp-rx"](1)
    assert np.array_equal(a.y, b.y) and not np.array_equal(a.y, c.y)
    clean = ps.model().simulate(a.u)
    np.testing.assert_allclose((a.y - clean).std(axis=0), ps.NOISE_STD, rtol=0.05)
    assert np.all(a.u[:, [0, 2]] == 0) and np.ptp(a.u[:, 1]) == pytest.approx(400, rel=1e-3)
    chirp = ps.EXPERIMENTS["chirp-z"](0).u[:, 0]
    assert chirp.mean() == pytest.approx(20.0, abs=0.5)
