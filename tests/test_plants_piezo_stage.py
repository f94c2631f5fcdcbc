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


# ------------------------------------------------------------- an independent reading of the paper
# Eq. 23-25 of Cao & Chen (2013), typed in again by hand from the paper's text
# (../shared/papers/cao-chen-2013-hankel-map-3dof-piezo-stage.txt, lines 256-264), row by row as
# printed, without looking at stageid.plants.piezo_stage.  Reading of the OCR: "0.4", "-0.1",
# "0.011", "0.072", ... are 4-decimal numbers with the trailing zeros dropped; A1[6, 4] is printed
# "0.00008" and kept (0.0008 would move no pole by more than 8e-5 and keep every sub-model stable,
# so nothing argues against the printed digits); eq. 19's "A_i in R^{3x3}" is a typo for the
# orders 7, 4, 4 the text chose; the second "D_2" after eq. 25 is D_3; every D_i is zero.
PAPER_EQ_23_25 = """
A1
0.9239 -0.1747 0.0057 -0.0297 -0.0026 -0.0045 -0.0004
0.1757 0.6973 0.0604 -0.2463 -0.0262 -0.0333 -0.0031
0.0219 -0.1592 0.8761 -0.0622 -0.0504 -0.0266 0.0110
-0.0291 0.2297 0.4000 0.4512 -0.1000 0.1691 0.0169
-0.0101 0.0321 0.0950 -0.1506 0.9447 0.1266 0.0155
-0.0068 0.0231 0.0439 -0.3232 -0.1645 0.6283 -0.0277
-0.0044 0.0093 0.1160 -0.0850 0.00008 -0.1766 0.8136
B1
0.3094
-0.2819
-0.0608
0.0912
0.0185
0.0199
0.0061
C1
0.3052 0.2798 -0.0221 0.0891 0.0073 0.0153 0.0018
0.0134 0.0259 0.0453 0.0533 0.0381 -0.0397 -0.0108
0.0033 -0.0215 0.0189 -0.0416 -0.0061 0.0375 -0.0039
A2
0.9493 0.1175 0.0173 0.0233
-0.1161 0.7929 -0.1205 -0.1509
-0.0001 0.0720 0.9273 -0.2011
0.0238 0.1573 0.0285 0.7314
B2
0.2595
0.2232
-0.0325
-0.0693
C2
-0.00002 -0.00001 -0.00002 -0.00024
0.2402 -0.2215 -0.0502 -0.0687
-0.0002 -0.00053 -0.00049 -0.0011
A3
0.9485 0.1204 -0.0134 0.0261
-0.1184 0.7981 0.0779 -0.1711
0.0030 -0.0094 0.9656 0.1719
0.0225 0.1825 -0.0783 0.7110
B3
-0.2574
-0.2229
-0.0150
0.0775
C3
-0.00002 -0.00001 -0.0001 -0.00022
0.0043 -0.0018 -0.0031 -0.0028
-0.2390 0.2205 -0.0376 0.0762
"""


def _paper_matrices() -> dict[str, np.ndarray]:
    mats, name = {}, None
    for line in PAPER_EQ_23_25.strip().splitlines():
        if line[0].isalpha():
            name = line.strip()
            mats[name] = []
        else:
            mats[name].append([float(v) for v in line.split()])
    return {k: np.array(v) for k, v in mats.items()}


def _paper_channels() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    M = _paper_matrices()
    return [(M[f"A{i}"], M[f"B{i}"], M[f"C{i}"]) for i in (1, 2, 3)]


def test_reference_matches_an_independent_reading_of_eq_23_25():
    chans = _paper_channels()
    assert [(A.shape, B.shape, C.shape) for A, B, C in chans] == [
        ((7, 7), (7, 1), (3, 7)),
        ((4, 4), (4, 1), (3, 4)),
        ((4, 4), (4, 1), (3, 4)),
    ]
    g, subs = ps.model(), ps.channel_models()
    z = np.exp(2j * np.pi * np.linspace(0.1, 250.0, 400) * 0.002)  # 0.1 Hz to Nyquist
    f = np.angle(z) / (2 * np.pi * 0.002)
    # the typed numbers carry 4-5 significant digits: a transcription slip in one entry moves these
    # quantities by ~1e-4 or more, while both readings agreeing entry for entry gives ~1e-15
    tol = 1e-12
    for k, ((A, B, C), sub) in enumerate(zip(chans, subs)):
        # poles (eq. 23-25, channel by channel)
        np.testing.assert_allclose(
            np.sort_complex(sub.poles()), np.sort_complex(np.linalg.eigvals(A)), rtol=0, atol=tol
        )
        # DC gains C (I - A)^-1 B and the frequency response C (zI - A)^-1 B (D = 0)
        n = A.shape[0]
        np.testing.assert_allclose(sub.dc_gain()[:, 0], (C @ np.linalg.solve(np.eye(n) - A, B))[:, 0], atol=tol)
        G = np.array([(C @ np.linalg.solve(zk * np.eye(n) - A, B))[:, 0] for zk in z])
        np.testing.assert_allclose(sub.frequency_response(f)[:, :, 0], G, rtol=1e-10, atol=tol)
        np.testing.assert_allclose(g.frequency_response(f)[:, :, k], G, rtol=1e-10, atol=tol)  # eq. 20-22
        # Markov parameters D, CB, CAB, ... (40 of them: 80 ms, past the slowest 2.2 Hz pole's knee)
        markov = [np.zeros(3)] + [(C @ np.linalg.matrix_power(A, i) @ B)[:, 0] for i in range(39)]
        np.testing.assert_allclose(g.markov_parameters(40)[:, :, k], np.array(markov), rtol=0, atol=tol)
    poles = np.concatenate([np.linalg.eigvals(A) for A, _, _ in chans])
    np.testing.assert_allclose(np.sort_complex(g.poles()), np.sort_complex(poles), rtol=0, atol=tol)
    assert np.all(np.abs(poles) < 1)  # every sub-model stable, as a position-controlled stage is
