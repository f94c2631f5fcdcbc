"""Banded play and CP sums (blocks of 4 operators, LLVM vector code) against the references.

The banded kernels sort the operators into blocks of 4 (padded with inert operators), keep
up to 4 "hot" blocks in registers and update the others only when the input leaves their
band.  Every operator output must equal the plain-Python reference
(:func:`operators.play_reference`, :func:`operators.coupled_play_reference`) bit for bit; the
weighted sums are associated differently, so they are compared to 1e-12 of their largest
magnitude (the differences seen are ~1e-15).  Operator counts 1, 3, 4, 5, 8, 21 cover an
identity-only model, partial, exact and one-over blocks, and more hot blocks than registers
(21 operators: 6 blocks, of which 4 in registers and 1 or 2 in memory).
"""

import numpy as np
import pytest

from stageid.hysteresis import PIModel, kernels
from stageid.hysteresis.models.operators import coupled_play_reference, play_reference

N = 3000


def _walk(rng, n, step=5.0):
    return 450 - np.abs(np.mod(np.cumsum(rng.normal(0, step, n)) + 450, 1800) - 900)


def _input(kind, rng, grid, n=N):
    if kind == "random-walk":  # turns at every other sample
        return _walk(rng, n)
    if kind == "clipped-walk":  # long plateaus
        return np.clip(np.cumsum(rng.normal(0, 12, n)), -300, 300)
    if kind == "smooth":
        t = np.linspace(0, 1, n)
        return 400 * np.sin(2 * np.pi * 7 * t) * (1 - 0.9 * t)
    if kind == "jumps":  # every operator moves at almost every sample
        return rng.uniform(-450, 450, n)
    if kind == "on-thresholds":  # exact hits of switching points, with repeats
        return np.repeat(rng.choice(grid, size=n // 2 + 1), 2)[:n]
    if kind == "ulp-steps":  # one-ulp moves around the switching points
        base = rng.choice(grid, size=n)
        return np.where(rng.uniform(size=n) < 0.5, np.nextafter(base, np.inf), np.nextafter(base, -np.inf))
    raise ValueError(kind)


KINDS = ["random-walk", "clipped-walk", "smooth", "jumps", "on-thresholds", "ulp-steps"]
COUNTS = [1, 3, 4, 5, 8, 21]


def _play_thresholds(rng, m):
    r = np.sort(rng.uniform(0, 300, m))
    r[0] = 0.0  # an identity operator (a linear term)
    if m > 4:
        r[3] = r[2]  # equal thresholds
    return r


def _cp_thresholds(rng, m):
    r = np.sort(rng.uniform(0, 300, m))
    rc = r * rng.uniform(0, 1, m)
    ra = r * rng.uniform(0.5, 2, m)
    rb = ra * rng.uniform(0, 1, m)
    r[0] = rc[0] = ra[0] = rb[0] = 0.0
    if m > 2:
        rc[1] = 0.0
        rb[2] = 0.0
    return r, rc, ra, rb


def _n_hot_values(m):
    nb = max((m - 1 + 3) // 4, 1)
    return sorted({-1, 0, 1, 2, nb - 1, nb, nb + 3})


def _check_sum(y, yr, name):
    # sums associated differently: 1e-12 of the output scale (observed ~1e-15)
    np.testing.assert_allclose(y, yr, rtol=0, atol=1e-12 * max(np.abs(yr).max(), 1.0), err_msg=name)


@pytest.mark.parametrize("m", COUNTS)
@pytest.mark.parametrize("kind", KINDS)
def test_play_banded_equals_reference(kind, m):
    rng = np.random.default_rng(100 * m + KINDS.index(kind))
    r = _play_thresholds(rng, m)
    x = _input(kind, rng, np.unique(np.r_[r, -r, 0.0]))
    w = rng.normal(size=m)
    z0 = rng.uniform(-300, 300, m)  # not consistent with x[0]: the first sample fixes it
    Zr, zr = play_reference(x, r, z0)
    for n_hot in _n_hot_values(m):
        y, z = kernels.play_sum_banded(x, r, w, z0, 0.0, n_hot)
        assert np.array_equal(z, zr), f"n_hot={n_hot}: operator outputs differ by {np.abs(z - zr).max():.3g}"
        _check_sum(y, Zr @ w, f"play n_hot={n_hot}")


@pytest.mark.parametrize("m", COUNTS)
@pytest.mark.parametrize("kind", ["random-walk", "jumps", "ulp-steps"])
def test_cp_banded_block_edges(kind, m):
    rng = np.random.default_rng(200 * m + KINDS.index(kind))
    r, rc, ra, rb = _cp_thresholds(rng, m)
    grid = np.unique(np.r_[r, -r, rc, -rc, ra, -ra, rb, -rb, 0.0])
    x = _input(kind, rng, grid)
    w = rng.normal(size=m)
    z0 = rng.uniform(-300, 300, m)
    Zr, zr = coupled_play_reference(x, r, rc, ra, rb, z0)
    for n_hot in _n_hot_values(m):
        y, z = kernels.cp_sum_banded(x, r, rc, ra, rb, w, z0, 0.0, n_hot)
        assert np.array_equal(z, zr), f"n_hot={n_hot}: operator outputs differ by {np.abs(z - zr).max():.3g}"
        _check_sum(y, Zr @ w, f"CP n_hot={n_hot}")


def test_play_banded_at_the_activation_points():
    # an adversary: each sample goes to (or one ulp either side of) the point where some
    # operator of the current state starts to move, or creeps by 1e-12 from there
    rng = np.random.default_rng(5)
    m = 9
    r = _play_thresholds(rng, m)
    z = np.zeros(m)
    xs = np.empty(N)
    xk = 0.0
    for k in range(N):
        i = rng.integers(m)
        a = z[i] + r[i] if rng.uniform() < 0.5 else z[i] - r[i]
        step = np.sign(a - xk) * 1e-12 * (1.0 + abs(a))
        xk = [a, np.nextafter(a, np.inf), np.nextafter(a, -np.inf), a + step, xk + step][rng.integers(5)]
        z = np.maximum(xk - r, np.minimum(xk + r, z))
        xs[k] = xk
    w = rng.normal(size=m)
    Zr, zr = play_reference(xs, r, np.zeros(m))
    for n_hot in (-1, 0, 1, 2):
        y, zb = kernels.play_sum_banded(xs, r, w, np.zeros(m), 0.0, n_hot)
        assert np.array_equal(zb, zr), n_hot
        _check_sum(y, Zr @ w, f"n_hot={n_hot}")


@pytest.mark.parametrize("kind", ["random-walk", "jumps"])
def test_play_banded_resume_from_saved_state(kind):
    rng = np.random.default_rng(17)
    r = _play_thresholds(rng, 13)
    x = _input(kind, rng, r)
    w = rng.normal(size=13)
    Zr, zr = play_reference(x, r, np.zeros(13))
    for call in (kernels.play_sum_banded, kernels.play_sum_auto):
        z, x0, ys = np.zeros(13), 0.0, []
        for part in np.split(x, [1, 1200, 1201, 2500]):  # a one-sample record in between
            y, z = call(part, r, w, z, x0)
            ys.append(y)
            x0 = float(part[-1])
        _check_sum(np.concatenate(ys), Zr @ w, call.__name__)
        np.testing.assert_allclose(z, zr, rtol=0, atol=1e-12 * 450)  # auto: events rebuild at reversals
        if call is kernels.play_sum_banded:
            assert np.array_equal(z, zr)


def test_long_records_with_adaptation_equal_the_loop_kernels():
    # > 32 choices of the number of hot blocks (every 2048 samples), on a walk whose step
    # changes so the choice moves; the loop kernels are bit-equal to the references (tested
    # in test_hysteresis_kernels_speedpath.py)
    rng = np.random.default_rng(8)
    n = 80_000
    x = np.concatenate([_walk(rng, n // 4, s) for s in (5.0, 40.0, 1.0, 200.0)])
    for m in (5, 21, 40):
        r, rc, ra, rb = _cp_thresholds(rng, m)
        w = rng.normal(size=m)
        z0 = rng.uniform(-100, 100, m)
        yl, zl = kernels.cp_sum(x, r, rc, ra, rb, w, z0)
        y, z = kernels.cp_sum_banded(x, r, rc, ra, rb, w, z0)
        assert np.array_equal(z, zl)
        _check_sum(y, yl, f"CP m={m}")
        yl, zl = kernels.play_sum(x, r, w, z0)
        y, z = kernels.play_sum_banded(x, r, w, z0)
        assert np.array_equal(z, zl)
        _check_sum(y, yl, f"play m={m}")


def test_play_banded_edge_cases():
    r = np.array([0.0, 1.0, 2.0])
    w = np.array([1.0, 2.0, 0.5])
    z0 = np.array([0.0, 1.0, -1.0])
    y, z = kernels.play_sum_banded(np.empty(0), r, w, z0)
    assert y.shape == (0,) and np.array_equal(z, z0) and z is not z0
    x = np.array([3.0])
    y, z = kernels.play_sum_banded(x, r, w, z0)
    Zr, zr = play_reference(x, r, z0)
    assert np.array_equal(z, zr) and np.allclose(y, Zr @ w, rtol=0, atol=1e-12)
    # only identity operators (a linear term): y = sum(w) x
    zero = np.zeros(3)
    x = np.array([0.0, 2.0, -1.0, -1.0, 3.5])
    y, z = kernels.play_sum_banded(x, zero, w, zero)
    assert np.array_equal(y, 3.5 * x) and np.array_equal(z, np.full(3, 3.5))
    # a strided input (a view) gives the same as its contiguous copy
    x = _walk(np.random.default_rng(1), 2000)
    r = np.linspace(0, 100, 6)
    w6 = np.linspace(1, 2, 6)
    for call in (
        lambda xx: kernels.play_sum_banded(xx, r, w6, np.zeros(6)),
        lambda xx: kernels.cp_sum_banded(xx, r, 0.5 * r, r, 0.5 * r, w6, np.zeros(6)),
    ):
        ys, zs = call(x[::2])
        yc, zc = call(np.ascontiguousarray(x[::2]))
        assert np.array_equal(ys, yc) and np.array_equal(zs, zc)
    # the caller's arrays are not modified
    x = _walk(np.random.default_rng(0), 500)
    r = np.linspace(0, 100, 6)
    w = np.linspace(0.5, 1.5, 6)
    z0 = np.linspace(-5, 5, 6)
    keep = [a.copy() for a in (x, r, w, z0)]
    y, z = kernels.play_sum_banded(x, r, w, z0)  # every array snapshotted is the one passed in
    assert all(np.array_equal(a, b) for a, b in zip((x, r, w, z0), keep))
    assert z is not z0 and not np.shares_memory(z, z0)  # the final state is a new array
    Zr, zr = play_reference(x, r, z0)
    assert np.array_equal(z, zr) and np.allclose(y, Zr @ w, rtol=0, atol=1e-9 * np.abs(y).max())


def test_pi_model_simulate_on_a_random_walk_equals_reference():
    rng = np.random.default_rng(4)
    r = np.arange(20) * 22.5
    w = np.r_[1.0, rng.uniform(0, 0.3, 19)]
    model = PIModel(r=r, weights=w)
    u = _walk(rng, 4000)
    y = model.simulate(u)[:, 0]
    Zr, _ = play_reference(model.to_operator_input(u), r, np.zeros(20))
    yr = Zr @ w + model.output_offset
    _check_sum(y, yr, "PIModel.simulate")


def test_dispatch_on_long_records():
    # records longer than the 65536-sample head the dispatch looks at first
    rng = np.random.default_rng(9)
    n = 100_000
    assert not kernels.is_smooth(_walk(rng, n))
    smooth = np.sin(np.linspace(0, 40, n))
    assert kernels.is_smooth(smooth)
    late = smooth.copy()
    late[80_000:] += rng.normal(0, 1e-3, n - 80_000)  # rough only after the head
    assert not kernels.is_smooth(late)
