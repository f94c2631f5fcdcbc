"""CP-sum kernels (loop, event-driven, banded, auto) against the plain reference.

The reference is :func:`stageid.hysteresis.operators.coupled_play_reference` (plain Python,
eq. 3 in the consistent reading).  Every kernel computes each operator output with the same
floating-point operations as the reference, so the final operator outputs must be bit-equal
(the event kernel rebuilds them at reversals: 1e-12 of the input range); the weighted sums
are associated differently, so the model outputs are compared to 1e-12 of their largest
magnitude (the differences seen are ~2e-15).

Inputs: a random walk that turns at every other sample, one clipped to the range (long
plateaus), a smooth decaying sine, jumps over the whole range, full-range alternation,
inputs sitting exactly on the thresholds, and steps of one ulp around them; thresholds like
the benchmark's (``r = 0`` identity operator first) and random ones with zeros and equal pairs.
Records are longer than the banded kernel's adaptation block (2048 samples), so its choice
of hot blocks changes during the record.
"""

import numpy as np
import pytest

from stageid.hysteresis import ModifiedPIModel, OperatorState, kernels
from stageid.hysteresis.models.operators import coupled_play_reference, play_reference

N = 5000  # > 2 adaptation blocks of the banded kernel; the reference takes ~0.1 s


def _bench_thresholds(m):
    r = np.arange(m) * 450.0 / m
    rc, ra = 0.5 * r, 1.3 * r
    return r, rc, ra, 0.6 * ra


def _random_thresholds(rng, m):
    r = np.sort(rng.uniform(0, 300, m))
    rc = r * rng.uniform(0, 1, m)
    ra = r * rng.uniform(0.5, 2, m)
    rb = ra * rng.uniform(0, 1, m)
    r[0] = rc[0] = ra[0] = rb[0] = 0.0  # an identity operator
    rc[1] = 0.0  # no flat part below zero
    rb[2] = 0.0
    rc[3] = r[3]  # CP = play with thresholds r / ra
    rb[4] = ra[4]
    return r, rc, ra, rb


def _input(kind, rng, n=N, thresholds=None):
    if kind == "random-walk":  # reflected into +-450: turns at every other sample
        walk = np.cumsum(rng.normal(0, 5, n))
        return 450 - np.abs(np.mod(walk + 450, 1800) - 900)
    if kind == "clipped-walk":
        return np.clip(np.cumsum(rng.normal(0, 12, n)), -300, 300)
    if kind == "smooth":
        t = np.linspace(0, 1, n)
        return 400 * np.sin(2 * np.pi * 7 * t) * (1 - 0.9 * t)
    if kind == "jumps":
        return rng.uniform(-450, 450, n)
    if kind == "alternating":
        return 450 * (-1.0) ** np.arange(n)
    r, rc, ra, rb = thresholds
    grid = np.unique(np.r_[r, -r, rc, -rc, ra, -ra, rb, -rb, r - rc, ra - rb, 0.0])
    if kind == "on-thresholds":  # exact hits of every switching point, with repeats
        return np.repeat(rng.choice(grid, size=n // 2 + 1), 2)[:n]
    if kind == "ulp-steps":  # one-ulp moves around the switching points
        base = rng.choice(grid, size=n)
        return np.where(rng.uniform(size=n) < 0.5, np.nextafter(base, np.inf), np.nextafter(base, -np.inf))
    raise ValueError(kind)


KINDS = ["random-walk", "clipped-walk", "smooth", "jumps", "alternating", "on-thresholds", "ulp-steps"]


def _activation_walk(rng, r, rc, ra, rb, z0, n):
    """An adversary: each sample goes to (or one ulp either side of, or a hair beyond) the point
    where some operator of the current state starts to move, or creeps by 1e-12 from there."""
    z = z0.copy()
    xs = np.empty(n)
    xk = 0.0
    for k in range(n):
        i = rng.integers(r.size)
        rising = rng.uniform() < 0.5
        if rising:
            a = z[i] + (rc[i] if z[i] < 0 else r[i])
        else:
            a = z[i] - (rb[i] if z[i] > 0 else ra[i])
        step = (1.0 if rising else -1.0) * 1e-12 * (1.0 + abs(a))
        xk = [a, np.nextafter(a, np.inf), np.nextafter(a, -np.inf), a + step, xk + step][rng.integers(5)]
        up = np.maximum(xk - r, np.minimum(xk - rc, 0.0))
        down = np.minimum(xk + ra, np.maximum(xk + rb, 0.0))
        z = np.maximum(up, np.minimum(down, z))
        xs[k] = xk
    return xs


def _consistent_state(rng, x0, r, rc, ra, rb):
    up = np.maximum(x0 - r, np.minimum(x0 - rc, 0.0))
    down = np.minimum(x0 + ra, np.maximum(x0 + rb, 0.0))
    return np.maximum(up, np.minimum(down, rng.uniform(-200, 200, r.size)))


def _kernel_calls(x, r, rc, ra, rb, w, z0, x0):
    return {
        "loop": lambda: kernels.cp_sum(x, r, rc, ra, rb, w, z0),
        "events": lambda: kernels.cp_sum_events(x, r, rc, ra, rb, w, z0, x0),
        "banded": lambda: kernels.cp_sum_banded(x, r, rc, ra, rb, w, z0, x0),
        "auto": lambda: kernels.cp_sum_auto(x, r, rc, ra, rb, w, z0, x0),
    }


def _check(name, y, z, Zr, zr, w):
    yr = Zr @ w
    # sums associated differently: 1e-12 of the output scale (observed ~2e-15)
    np.testing.assert_allclose(y, yr, rtol=0, atol=1e-12 * max(np.abs(yr).max(), 1.0), err_msg=name)
    if name == "events":  # outputs rebuilt from the stretch's start state at reversals
        np.testing.assert_allclose(z, zr, rtol=0, atol=1e-12 * 450, err_msg=name)
    else:
        assert np.array_equal(z, zr), f"{name}: final operator outputs differ by {np.abs(z - zr).max():.3g}"


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("thresholds", ["benchmark", "random"])
def test_every_kernel_equals_reference(kind, thresholds):
    rng = np.random.default_rng(KINDS.index(kind) + 10 * (thresholds == "random"))
    m = 12
    r, rc, ra, rb = _bench_thresholds(m) if thresholds == "benchmark" else _random_thresholds(rng, m)
    x = _input(kind, rng, thresholds=(r, rc, ra, rb))
    w = rng.normal(size=m)
    x0 = float(x[0])
    z0 = _consistent_state(rng, x0, r, rc, ra, rb)
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    for name, call in _kernel_calls(x, r, rc, ra, rb, w, z0, x0).items():
        y, z = call()
        _check(name, y, z, Zr, zr, w)


@pytest.mark.parametrize("thresholds", ["benchmark", "random"])
def test_every_kernel_at_the_activation_points(thresholds):
    rng = np.random.default_rng(21 + (thresholds == "random"))
    m = 10
    r, rc, ra, rb = _bench_thresholds(m) if thresholds == "benchmark" else _random_thresholds(rng, m)
    z0 = np.zeros(m)
    x = _activation_walk(rng, r, rc, ra, rb, z0, 3000)
    w = rng.normal(size=m)
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    for name, call in _kernel_calls(x, r, rc, ra, rb, w, z0, 0.0).items():
        y, z = call()
        _check(name, y, z, Zr, zr, w)
    for n_hot in (0, 1, 2):
        y, z = kernels.cp_sum_banded(x, r, rc, ra, rb, w, z0, 0.0, n_hot)
        _check(f"banded n_hot={n_hot}", y, z, Zr, zr, w)


@pytest.mark.parametrize("kind", ["random-walk", "jumps", "on-thresholds"])
def test_banded_every_number_of_hot_blocks(kind):
    # 21 operators (one identity): 5 blocks of 4; 0..5 hot blocks (up to 4 of them in
    # registers, the fifth in memory) and more than there are, fixed and adaptive
    rng = np.random.default_rng(7)
    r, rc, ra, rb = _random_thresholds(rng, 21)
    x = _input(kind, rng, n=3000, thresholds=(r, rc, ra, rb))
    w = rng.normal(size=21)
    z0 = rng.uniform(-100, 100, 21)  # not consistent with x[0]: the first sample fixes it
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    for n_hot in (-1, 0, 1, 2, 3, 5):
        y, z = kernels.cp_sum_banded(x, r, rc, ra, rb, w, z0, 0.0, n_hot)
        _check(f"banded n_hot={n_hot}", y, z, Zr, zr, w)


def test_loop_and_banded_from_an_inconsistent_state():
    rng = np.random.default_rng(3)
    r, rc, ra, rb = _bench_thresholds(20)
    x = _input("random-walk", rng, n=3000)
    w = rng.uniform(0, 1, 20)
    z0 = rng.uniform(-500, 500, 20)
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    for name in ("loop", "banded"):
        y, z = _kernel_calls(x, r, rc, ra, rb, w, z0, 123.0)[name]()
        _check(name, y, z, Zr, zr, w)


@pytest.mark.parametrize("kind", ["random-walk", "smooth", "jumps"])
def test_resume_from_saved_state(kind):
    rng = np.random.default_rng(11)
    r, rc, ra, rb = _random_thresholds(rng, 10)
    x = _input(kind, rng, n=4000, thresholds=(r, rc, ra, rb))
    w = rng.normal(size=10)
    z0 = np.zeros(10)
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    for name in ("loop", "events", "banded", "auto"):
        z, x0, ys = z0, 0.0, []
        for part in np.split(x, [1, 1500, 1501, 3100]):  # a one-sample record in between
            y, z = _kernel_calls(part, r, rc, ra, rb, w, z, x0)[name]()
            ys.append(y)
            x0 = float(part[-1])
        _check(f"{name} resumed", np.concatenate(ys), z, Zr, zr, w)


@pytest.mark.parametrize("kind", ["random-walk", "clipped-walk", "smooth", "jumps", "on-thresholds"])
def test_play_sum_auto_equals_reference(kind):
    # the classical PI's kernel: events on smooth records, the banded CP kernel with
    # rc = ra = rb = r otherwise -- the play's operator outputs bit for bit
    rng = np.random.default_rng(31 + KINDS.index(kind))
    r = np.r_[0.0, np.sort(rng.uniform(0, 300, 11))]
    x = _input(kind, rng, thresholds=(r, r, r, r))
    w = rng.normal(size=12)
    x0 = float(x[0])
    z0 = np.maximum(x0 - r, np.minimum(x0 + r, rng.uniform(-200, 200, 12)))
    Zr, zr = play_reference(x, r, z0)
    y, z = kernels.play_sum_auto(x, r, w, z0, x0)
    np.testing.assert_allclose(y, Zr @ w, rtol=0, atol=1e-12 * np.abs(Zr @ w).max())
    np.testing.assert_allclose(z, zr, rtol=0, atol=1e-12 * 450)  # events: rebuilt at reversals
    y, z = kernels.cp_sum_banded(x, r, r, r, r, w, z0, x0)
    assert np.array_equal(z, zr)


def test_edge_cases():
    r, rc, ra, rb = _bench_thresholds(5)
    w = np.ones(5)
    z0 = np.array([0.0, 1.0, -1.0, 0.5, 0.0])
    for name, call in _kernel_calls(np.empty(0), r, rc, ra, rb, w, z0, 0.0).items():
        y, z = call()
        assert y.shape == (0,) and np.array_equal(z, z0), name
    # only identity operators (a linear term): y = sum(w) x
    zero = np.zeros(3)
    x = np.array([0.0, 2.0, -1.0, -1.0, 3.5])
    y, z = kernels.cp_sum_banded(x, zero, zero, zero, zero, np.array([1.0, 2.0, 0.5]), zero, 0.0)
    assert np.array_equal(y, 3.5 * x) and np.array_equal(z, np.full(3, 3.5))


def test_turn_fraction():
    assert kernels.turn_fraction(np.array([0.0, 1.0, 0.0, 1.0, 0.0])) == 3 / 5
    assert kernels.turn_fraction(np.arange(10.0)) == 0.0
    assert kernels.turn_fraction(np.array([0.0, 1.0, 1.0, 0.0])) == 0.0  # turns across a plateau are not seen
    assert kernels.turn_fraction(np.empty(0)) == 0.0
    # the dispatch: a sine is smooth; a square wave turns only across plateaus, yet reverses often
    assert kernels.is_smooth(np.sin(np.linspace(0, 20, 10_000)))
    assert not kernels.is_smooth(np.repeat((-1.0) ** np.arange(1000), 10))
    assert not kernels.is_smooth(np.random.default_rng(0).normal(size=10_000))


@pytest.mark.parametrize("kind", ["random-walk", "smooth"])
def test_modified_pi_simulate_equals_reference(kind):
    rng = np.random.default_rng(5)
    r, rc, ra, rb = _bench_thresholds(20)
    w = np.r_[1.0, rng.uniform(0, 0.3, 19)]
    model = ModifiedPIModel(r=r, rc=rc, ra=ra, rb=rb, weights=w)
    u = _input(kind, rng, n=4000)
    y = model.simulate(u)[:, 0]
    Zr, zr = coupled_play_reference(model.to_operator_input(u), r, rc, ra, rb, np.zeros(20))
    yr = Zr @ w + model.output_offset
    np.testing.assert_allclose(y, yr, rtol=0, atol=1e-12 * np.abs(yr).max())
    # resumed from the saved state of the first half
    y1, s1 = model.run(u[:2000])
    y2, s2 = model.with_state(s1).run(u[2000:])
    np.testing.assert_allclose(np.r_[y1[:, 0], y2[:, 0]], yr, rtol=0, atol=1e-12 * np.abs(yr).max())
    np.testing.assert_allclose(s2.z, zr, rtol=0, atol=1e-12 * 450)
    assert isinstance(s2, OperatorState)
