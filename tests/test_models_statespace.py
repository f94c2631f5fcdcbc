"""StateSpaceModel and TransferMatrix against analytic truth and python-control."""

import numpy as np
import pytest

from stageid import ModelError
from stageid.models import StateSpaceModel, TransferMatrix, c2d, d2c, feedback, minimal_realization, series


def random_stable(rng, n, m, p, dt=None):
    if dt is None:
        A = rng.standard_normal((n, n))
        A = A - (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)
    else:
        A = rng.standard_normal((n, n))
        A = 0.9 * A / np.max(np.abs(np.linalg.eigvals(A)))
    return StateSpaceModel(A, rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m)), dt)


def test_simulate_equals_recursion():
    rng = np.random.default_rng(1)
    g = random_stable(rng, 5, 2, 3, dt=0.002)
    u = rng.standard_normal((5000, 2))  # long enough to take the compiled path
    x = np.zeros(5)
    y_ref = np.empty((5000, 3))
    for k in range(5000):
        y_ref[k] = g.C @ x + g.D @ u[k]
        x = g.A @ x + g.B @ u[k]
    np.testing.assert_allclose(g.simulate(u), y_ref, rtol=0, atol=1e-10)  # same arithmetic, rounding only
    np.testing.assert_allclose(g.simulate(u[:50]), y_ref[:50], rtol=0, atol=1e-12)


def test_simulate_does_not_modify_input():
    rng = np.random.default_rng(2)
    g = random_stable(rng, 3, 1, 1, dt=0.1)
    u = rng.standard_normal((3000, 1))
    before = u.copy()
    g.simulate(u)
    np.testing.assert_array_equal(u, before)


def test_frequency_response_continuous_matches_formula():
    rng = np.random.default_rng(3)
    g = random_stable(rng, 4, 2, 2)
    f = np.array([0.0, 0.3, 2.0, 50.0])
    fr = g.frequency_response(f)
    for k, fk in enumerate(f):
        s = 2j * np.pi * fk
        expected = g.C @ np.linalg.solve(s * np.eye(4) - g.A, g.B) + g.D
        np.testing.assert_allclose(fr[k], expected, rtol=1e-12, atol=1e-12)


def test_frequency_response_discrete_and_dc_gain():
    g = StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.1)
    np.testing.assert_allclose(g.dc_gain(), [[2.0]])
    f = 1.7
    z = np.exp(2j * np.pi * f * 0.1)
    np.testing.assert_allclose(g.frequency_response([f])[0, 0, 0], 1.0 / (z - 0.5), rtol=1e-13)


def test_dc_gain_of_integrator_is_an_error():
    with pytest.raises(ModelError, match="pole at s = 0"):
        StateSpaceModel([[0.0]], [[1.0]], [[1.0]], [[0.0]]).dc_gain()


def test_poles_and_zeros_of_known_system():
    # G(s) = (s + 3) / ((s + 1)(s + 2))
    t = TransferMatrix([[[1.0, 3.0]]], [[[1.0, 3.0, 2.0]]])
    np.testing.assert_allclose(np.sort(t.poles().real), [-2.0, -1.0], atol=1e-10)
    np.testing.assert_allclose(t.to_statespace().zeros().real, [-3.0], atol=1e-9)
    np.testing.assert_allclose(t.zeros().real, [-3.0], atol=1e-12)


def test_zeros_of_the_realisation_as_given_keep_decoupling_zeros():
    # diag(-1, -5) with the second state unobservable: G(s) = 1/(s + 1), the mode at -5 a decoupling zero
    g = StateSpaceModel([[-1.0, 0.0], [0.0, -5.0]], [[1.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    assert g.zeros().size == 0  # minimal realisation: no zero
    np.testing.assert_allclose(g.zeros(minimal=False).real, [-5.0], atol=1e-10)


def test_shape_error_names_field_and_shapes():
    with pytest.raises(ModelError, match=r"`B` must have shape \(2, 1\); got \(3, 1\)"):
        StateSpaceModel(np.eye(2), np.ones((3, 1)), np.ones((1, 2)), np.zeros((1, 1)))


def test_arrays_are_read_only_copies():
    A = np.eye(2) * 0.5
    g = StateSpaceModel(A, np.ones((2, 1)), np.ones((1, 2)), np.zeros((1, 1)), dt=1.0)
    A[0, 0] = 9.0
    assert g.A[0, 0] == 0.5
    with pytest.raises(ValueError):
        g.A[0, 0] = 1.0


@pytest.mark.parametrize("method", ["zoh", "tustin"])
def test_c2d_d2c_round_trip(method):
    rng = np.random.default_rng(4)
    g = random_stable(rng, 4, 2, 2)
    back = d2c(c2d(g, 0.01, method), method)
    f = np.geomspace(0.1, 20, 15)
    np.testing.assert_allclose(back.frequency_response(f), g.frequency_response(f), rtol=1e-7, atol=1e-9)


def test_c2d_zoh_matches_python_control():
    import control

    rng = np.random.default_rng(5)
    g = random_stable(rng, 3, 1, 2)
    ours = c2d(g, 0.05)
    theirs = control.c2d(g.to_control(), 0.05, method="zoh")
    f = np.linspace(0.0, 9.0, 10)
    np.testing.assert_allclose(
        ours.frequency_response(f), StateSpaceModel.from_control(theirs).frequency_response(f), rtol=1e-10, atol=1e-12
    )


def test_d2c_without_real_logarithm_is_a_clear_error():
    g = StateSpaceModel([[-0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.1)
    with pytest.raises(ModelError, match="no real matrix logarithm"):
        d2c(g)


def test_transfer_matrix_simulation_matches_statespace():
    rng = np.random.default_rng(6)
    g = random_stable(rng, 4, 2, 2, dt=0.01)
    t = TransferMatrix.from_statespace(g)
    u = rng.standard_normal((400, 2))
    np.testing.assert_allclose(t.simulate(u), g.simulate(u), rtol=1e-8, atol=1e-8)
    f = np.linspace(0.0, 40.0, 7)
    np.testing.assert_allclose(t.frequency_response(f), g.frequency_response(f), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(np.sort_complex(t.poles()), np.sort_complex(g.poles()), atol=1e-8)


def test_minimal_realization_removes_hidden_modes():
    A = np.diag([-1.0, -2.0, -3.0])
    g = StateSpaceModel(A, [[1.0], [0.0], [1.0]], [[1.0, 1.0, 0.0]], [[0.0]])
    m = minimal_realization(g)
    assert m.n_states == 1
    np.testing.assert_allclose(m.poles().real, [-1.0], atol=1e-12)


@pytest.mark.parametrize("gain", [1e-13, 1e-7, 1.0, 1e7])
def test_minimal_realization_does_not_depend_on_the_units_of_b_and_c(gain):
    # a stage in metres per volt has B ~ 1e-7: an absolute rank threshold removed every state
    A = 1e3 * np.diag([-1.0, -2.0, -3.0, -4.0])
    B = gain * np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.0, 0.0]])  # 4th mode not driven
    C = gain * np.array([[1.0, 1.0, 0.0, 1.0], [0.0, 1.0, 1.0, 1.0]])
    g = StateSpaceModel(A, B, C, np.zeros((2, 2)))
    m = minimal_realization(g)
    assert m.n_states == 3
    np.testing.assert_allclose(np.sort(m.poles().real), [-3e3, -2e3, -1e3], rtol=1e-9)
    f = np.array([0.0, 10.0, 300.0])
    np.testing.assert_allclose(m.frequency_response(f), g.frequency_response(f), rtol=1e-9, atol=0)


def test_feedback_matches_python_control():
    import control

    G = StateSpaceModel([[1.2, 0.1], [0.0, 0.8]], [[1.0], [0.5]], [[1.0, 0.0]], [[0.0]], dt=0.01)  # unstable
    K = StateSpaceModel([[0.3]], [[1.0]], [[-0.4]], [[0.9]], dt=0.01)
    cl = feedback(G, K)
    ref = control.feedback(control.series(K.to_control(), G.to_control()), 1)
    f = np.linspace(0.0, 40.0, 9)
    np.testing.assert_allclose(
        cl.frequency_response(f)[:, :1, :],
        StateSpaceModel.from_control(ref).frequency_response(f),
        rtol=1e-9,
        atol=1e-12,
    )
    u_of_r = control.feedback(K.to_control(), G.to_control())
    np.testing.assert_allclose(
        cl.frequency_response(f)[:, 1:, :],
        StateSpaceModel.from_control(u_of_r).frequency_response(f),
        rtol=1e-9,
        atol=1e-12,
    )
    assert cl.is_stable() and not G.is_stable()


def test_series_composes_frequency_responses():
    rng = np.random.default_rng(8)
    g1 = random_stable(rng, 2, 1, 2)
    g2 = random_stable(rng, 3, 2, 1)
    f = np.array([0.1, 1.0, 5.0])
    np.testing.assert_allclose(
        series(g1, g2).frequency_response(f), g2.frequency_response(f) @ g1.frequency_response(f), rtol=1e-10
    )


def test_control_round_trip_keeps_labels_and_dt():
    g = StateSpaceModel([[0.5]], [[1.0]], [[2.0]], [[0.0]], dt=0.002, inputs=("Z",), outputs=("z",))
    back = StateSpaceModel.from_control(g.to_control())
    assert back.inputs == ("Z",) and back.outputs == ("z",) and back.dt == 0.002
    t = TransferMatrix([[[1.0, 2.0]]], [[[1.0, 3.0, 5.0]]], None, ("a",), ("b",))
    t2 = TransferMatrix.from_control(t.to_control())
    np.testing.assert_allclose(t2.frequency_response([0.3, 3.0]), t.frequency_response([0.3, 3.0]), rtol=1e-12)


def test_complex_matrices_are_refused_not_truncated():
    # np.array(complex, dtype=float) would drop the imaginary part with only a ComplexWarning
    with pytest.raises(ModelError, match="`A` must be a real matrix; got complex entries"):
        StateSpaceModel(np.array([[0.5 + 0.1j]]), [[1.0]], [[1.0]], [[0.0]], dt=0.1)
