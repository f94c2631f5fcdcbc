"""Play and coupled-play operators: kernels against the plain reference, and the defining properties."""

import numpy as np
import pytest

from stageid import ModelError
from stageid.hysteresis import OperatorState, coupled_play, kernels, play
from stageid.hysteresis.models.operators import coupled_play_reference, play_reference


def _cp_params(rng, n=6):
    r = np.sort(rng.uniform(0, 100, n))
    rc = r * rng.uniform(0, 1, n)
    ra = r * rng.uniform(0.5, 2, n)
    rb = ra * rng.uniform(0, 1, n)
    return r, rc, ra, rb


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kernels_equal_reference(seed):
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(0, 20, 2000))
    r, rc, ra, rb = _cp_params(rng)
    z0 = rng.uniform(-10, 10, r.size)
    Z, zf = kernels.cp_bank(x, r, rc, ra, rb, z0)
    Zr, zfr = coupled_play_reference(x, r, rc, ra, rb, z0)
    assert np.array_equal(Z, Zr) and np.array_equal(zf, zfr)  # same operations, same order: bit-equal
    Z, zf = kernels.play_bank(x, r, z0)
    Zr, _ = play_reference(x, r, z0)
    assert np.array_equal(Z, Zr)
    w = rng.normal(size=r.size)
    y, _ = kernels.cp_sum(x, r, rc, ra, rb, w, z0)
    # the weighted sum may be reassociated by the compiler: 1e-12 relative
    np.testing.assert_allclose(
        y, Zr_sum := coupled_play_reference(x, r, rc, ra, rb, z0)[0] @ w, rtol=1e-12, atol=1e-12 * np.abs(Zr_sum).max()
    )


def test_play_is_cp_with_equal_thresholds():
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(0, 10, 500))
    r = np.array([0.0, 5.0, 20.0])
    zp, _ = play(x, r)
    zc, _ = coupled_play(x, r, r, r, r)
    assert np.array_equal(zp, zc)


def test_play_matches_hand_computation():
    z, state = play([0.0, 2.0, 1.0, -2.0, 0.0], [1.0])
    assert z[:, 0].tolist() == [0.0, 1.0, 1.0, -1.0, -1.0]
    assert state.x == 0.0 and state.z.tolist() == [-1.0]


def test_initial_consistency_condition():
    # eq. 2 / eq. 3 with x0 = z0 = 0: z(0) = max(gamma_up(x(0)), min(gamma_down(x(0)), 0))
    r, rc, ra, rb = np.array([2.0]), np.array([1.0]), np.array([3.0]), np.array([1.5])
    for x0, expected in [(0.0, 0.0), (5.0, 3.0), (1.5, 0.0), (-2.0, 0.0), (-4.0, -1.0), (-10.0, -7.0)]:
        z, _ = coupled_play([x0], r, rc, ra, rb)
        assert z[0, 0] == expected
    # an explicit starting state is respected and clipped into the band
    z, _ = coupled_play([0.0], r, rc, ra, rb, OperatorState(0.0, [10.0]))
    assert z[0, 0] == 1.5  # gamma_down(0) = min(3, max(1.5, 0))


def test_rate_independence_refined_sampling():
    # inserting samples on monotone stretches between the original samples changes nothing there
    rng = np.random.default_rng(4)
    x = np.cumsum(rng.normal(0, 30, 300))
    r, rc, ra, rb = _cp_params(rng)
    coarse, _ = coupled_play(x, r, rc, ra, rb)
    fine_x = np.concatenate([np.linspace(a, b, 7, endpoint=False) for a, b in zip(x[:-1], x[1:])] + [x[-1:]])
    fine, _ = coupled_play(fine_x, r, rc, ra, rb)
    np.testing.assert_allclose(fine[::7], coarse, rtol=0, atol=1e-9)  # 1e-9: linspace rounding of x only


def test_rate_independence_time_scaling():
    rng = np.random.default_rng(5)
    r, rc, ra, rb = _cp_params(rng)
    t = np.linspace(0, 1, 1001)
    slow = 300 * np.sin(2 * np.pi * t)
    fast = 300 * np.sin(2 * np.pi * (t**2))  # same turning points visited at other times
    zs, _ = coupled_play(slow, r, rc, ra, rb)
    zf, _ = coupled_play(fast, r, rc, ra, rb)
    # at the maximum both have seen 0 -> 300 only
    assert np.allclose(zs[np.argmax(slow)], zf[np.argmax(fast)])


def test_wiping_out():
    r, rc, ra, rb = _cp_params(np.random.default_rng(6), 8)
    with_minor = np.array([0.0, 400, -300, 200, -100, 150, 0, 300])
    without = np.array([0.0, 400, -300, 300])
    z1, _ = coupled_play(with_minor, r, rc, ra, rb)
    z2, _ = coupled_play(without, r, rc, ra, rb)
    np.testing.assert_allclose(z1[-1], z2[-1], rtol=0, atol=1e-12)


def _branches(op, levels=(-200.0, 0.0, 200.0)):
    # major loop: 0 -> 400 -> -400 -> 400 -> -400, sampled every volt
    x = np.concatenate(
        [np.arange(0, 400), np.arange(400, -400, -1), np.arange(-400, 400), np.arange(400, -401, -1)]
    ).astype(float)
    z = op(x)[:, 0]
    rise = slice(1200, 2000)  # the second rise from -400
    fall = slice(2000, 2801)  # the second fall from +400
    up = [z[rise][np.flatnonzero(x[rise] == v)[0]] for v in levels]
    down = [z[fall][np.flatnonzero(x[fall] == -v)[0]] for v in levels]
    return np.array(up), np.array(down)


def test_asymmetry():
    r, rc, ra, rb = np.array([100.0]), np.array([30.0]), np.array([150.0]), np.array([60.0])
    up, down = _branches(lambda x: play(x, r)[0])
    np.testing.assert_allclose(up, -down, atol=1e-12)  # play loops are point-symmetric
    up, down = _branches(lambda x: coupled_play(x, r, rc, ra, rb)[0])
    # CP: upper-half width r + rb = 160, lower-half rc + ra = 180 -> not point-symmetric
    assert np.max(np.abs(up + down)) > 10.0


def test_state_resume():
    r, rc, ra, rb = np.array([100.0]), np.array([30.0]), np.array([150.0]), np.array([60.0])
    x = 400 * np.sin(np.linspace(0, 4 * np.pi, 801))
    z, _ = coupled_play(x, r, rc, ra, rb)
    a, sa = coupled_play(x[:333], r, rc, ra, rb)
    b, _ = coupled_play(x[333:], r, rc, ra, rb, sa)
    assert np.array_equal(np.vstack([a, b]), z)


def test_bad_thresholds():
    with pytest.raises(ModelError, match="rc <= r"):
        coupled_play([0.0], [1.0], [2.0], [1.0], [1.0])
    with pytest.raises(ModelError, match="rb <= ra"):
        coupled_play([0.0], [1.0], [1.0], [1.0], [2.0])
    with pytest.raises(ModelError, match=">= 0"):
        play([0.0], [-1.0])
    with pytest.raises(ModelError, match="shape"):
        play(np.zeros((3, 2)), [1.0])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_event_driven_play_sum_equals_reference(seed):
    rng = np.random.default_rng(seed)
    n = 4000
    smooth = 300 * np.sin(np.linspace(0, 25, n)) * np.linspace(1, 0.2, n)
    x = smooth + (rng.normal(0, 2, n) if seed % 2 else 0.0)
    x[500:520] = x[500]  # standing still
    r = np.r_[0.0, np.sort(rng.uniform(0, 250, 11))]
    w = rng.normal(size=12)
    for kind_state in range(3):
        x0 = float(rng.uniform(-100, 100))
        up, down = x0 - r, x0 + r
        z0 = [np.maximum(up, np.minimum(down, 0.0)), up, down][kind_state]
        Zr, zr = play_reference(x, r, z0)
        y, z = kernels.play_sum_events(x, r, w, z0, x0)
        np.testing.assert_allclose(y, Zr @ w, rtol=0, atol=1e-12 * np.abs(Zr @ w).max())
        np.testing.assert_allclose(z, zr, rtol=0, atol=1e-12 * 300)
        assert kernels.lipschitz_state(r, z0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_event_driven_cp_sum_equals_reference(seed):
    rng = np.random.default_rng(seed)
    n = 4000
    x = 300 * np.sin(np.linspace(0, 25, n)) * np.linspace(1, 0.2, n) + (rng.normal(0, 2, n) if seed % 2 else 0.0)
    x[500:520] = x[500]
    r, rc, ra, rb = _cp_params(rng, 10)
    w = rng.normal(size=10)
    x0 = float(rng.uniform(-60, 60))
    up = np.maximum(x0 - r, np.minimum(x0 - rc, 0.0))
    down = np.minimum(x0 + ra, np.maximum(x0 + rb, 0.0))
    z0 = np.maximum(up, np.minimum(down, rng.uniform(-40, 40, 10)))  # any consistent state
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    y, z = kernels.cp_sum_events(x, r, rc, ra, rb, w, z0, x0)
    np.testing.assert_allclose(y, Zr @ w, rtol=0, atol=1e-12 * np.abs(Zr @ w).max())
    np.testing.assert_allclose(z, zr, rtol=0, atol=1e-12 * 300)


def test_operator_input_errors_name_the_parameter_and_the_row():
    # the operators check their input with the models' one input check
    with pytest.raises(ModelError, match=r"input `x` must be finite; got nan at row 1"):
        play([0.0, float("nan")], [1.0])
    with pytest.raises(ModelError, match=r"input `x` must have shape"):
        coupled_play(np.zeros((3, 2)), [1.0], [0.5], [2.0], [1.0])
