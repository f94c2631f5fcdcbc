"""Inverses and the feedforward compensator: round trips, state duality, limits."""

import dataclasses

import numpy as np
import pytest

from stageid import ModelError
from stageid.hysteresis import Compensator, ModifiedPIModel, PIModel, compensate, invert, pi_inverse
from stageid.hysteresis.inverse import forward_state, inverse_state


def _pi(rng, n=10):
    r = np.arange(n) * 40.0
    w = np.r_[1.0, rng.uniform(-0.05, 0.4, n - 1)]
    return PIModel(r=r, weights=w, input_offset=5.0, output_offset=0.3)


def _mpi(rng, n=10):
    r = np.arange(n) * 40.0
    c, a, b = rng.uniform(0.2, 1, n), rng.uniform(0.5, 2, n), rng.uniform(0, 1, n)
    w = np.r_[1.0, rng.uniform(-0.05, 0.4, n - 1)]
    return ModifiedPIModel(
        r=r,
        rc=c * r,
        ra=a * r,
        rb=b * a * r,
        weights=w,
        output_offset=-0.4,
        input_offset=7.0,
        input_warp=float(rng.uniform(-0.3, 0.3)),
        warp_scale=300.0,
    )


def _drive(rng, n=3000):
    return 350 * np.sin(np.linspace(0, 12, n)) * np.linspace(1, 0.3, n) + np.cumsum(rng.normal(0, 2, n))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_closed_form_pi_inverse_round_trips(seed):
    rng = np.random.default_rng(seed)
    m = _pi(rng)
    u = _drive(rng)
    m = m.with_state(m.run(u[:500])[1])  # start from a non-trivial state
    y = m.simulate(u[500:])
    inv = pi_inverse(m)
    # inverse(model(u)) = u and model(inverse(y)) = y; 1e-9 V on hundreds of volts: rounding only
    np.testing.assert_allclose(inv.simulate(y), u[500:, None], rtol=0, atol=1e-9)
    yd = m.simulate(u[:1000])
    np.testing.assert_allclose(m.simulate(inv.simulate(yd)), yd, rtol=0, atol=1e-9)
    # the inverse of the inverse is the model (the duality of thresholds and weights)
    inv2 = pi_inverse(inv)
    np.testing.assert_allclose(inv2.r, m.r, atol=1e-9)
    np.testing.assert_allclose(inv2.weights, m.weights, atol=1e-12)


def test_state_duality():
    rng = np.random.default_rng(4)
    m = _pi(rng)
    st = m.run(_drive(rng))[1]
    inv = pi_inverse(m)
    back = forward_state(inv, inverse_state(m, st))
    np.testing.assert_allclose(back.z, st.z, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_modified_inversion_exact(seed):
    rng = np.random.default_rng(seed)
    m = _mpi(rng)
    yd = m.simulate(_drive(rng))[:, 0] + rng.normal(0, 0.5, 3000)  # also targets off the model's own path
    u, state = invert(m, yd)
    scale = np.sum(np.abs(m.weights)) * m.r.max()
    np.testing.assert_allclose(m.simulate(u)[:, 0], yd, rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(m.run(u)[1].z, state.z, rtol=0, atol=1e-9)  # u passes the warp and back: ulps


def test_generic_inversion_agrees_with_closed_form():
    rng = np.random.default_rng(5)
    m = _pi(rng)
    yd = m.simulate(_drive(rng))
    u1 = pi_inverse(m).simulate(yd)
    u2, _ = invert(m, yd)
    np.testing.assert_allclose(u1, u2, atol=1e-8)


@pytest.mark.parametrize("make", [_pi, _mpi])
def test_streaming_equals_batch_and_limits(make):
    rng = np.random.default_rng(6)
    m = make(rng)
    yd = m.simulate(_drive(rng))[:, 0] * 1.3  # beyond what +-300 V can reach
    comp = Compensator(m, limits=(-300.0, 300.0))
    step = np.array([comp.step(v) for v in yd])
    batch = compensate(m, yd, limits=(-300.0, 300.0))[:, 0]
    np.testing.assert_allclose(step, batch, atol=1e-9)
    assert step.min() >= -300.0 and step.max() <= 300.0 and (step == 300.0).any()
    # the compensator's state follows the clipped drive: it equals the model run on that drive
    np.testing.assert_allclose(comp.state.z, m.run(step)[1].z, atol=1e-8)
    # where no limit is hit, the model follows the target
    inside = np.abs(step) < 299.0
    np.testing.assert_allclose(m.simulate(step)[inside, 0], yd[inside], atol=1e-8)


def test_not_invertible():
    m = PIModel(r=[0.0, 1.0], weights=[1.0, -2.0])
    with pytest.raises(ModelError, match="not invertible"):
        pi_inverse(m)
    with pytest.raises(ModelError, match="not invertible"):
        invert(m.to_modified(), [0.0, 1.0])


def test_input_warp_round_trip():
    from stageid.hysteresis import ModifiedPIModel

    m = ModifiedPIModel(r=[0.0], weights=[1.0], input_offset=3.0, input_warp=0.3, warp_scale=100.0)
    u = np.linspace(-400, 400, 2001)  # also far outside the warp's quadratic part
    x = m.to_operator_input(u)
    assert np.all(np.diff(x) > 0)
    np.testing.assert_allclose(m.from_operator_input(x), u, rtol=0, atol=1e-9)


def _creep_pi():
    from stageid.hysteresis.models.creep import CreepTerm

    return PIModel(r=[0.0, 1.0], weights=[1.0, 0.5], creep=CreepTerm([0.5], [0.2], 0.01))


@pytest.mark.parametrize(
    "make",
    [
        lambda: PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]),
        lambda: PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]).to_modified(),
        lambda: PIModel(r=[0.0, 1.0], weights=[1.0, 0.5], input_offset=0.5).to_modified(),
        _creep_pi,
    ],
    ids=["pi", "modified-pi", "modified-pi-offset", "creep"],
)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_step_refuses_non_finite_and_keeps_state(make, bad):
    # regression: step(nan) used to return nan and poison every later drive (run() refused it)
    m = make()
    ref = [1.0, 1.0, 2.0, 0.5]
    clean = Compensator(m)
    expected = [clean.step(v) for v in ref]
    comp = Compensator(m)
    got = [comp.step(ref[0])]
    with pytest.raises(ModelError, match="must be finite; got"):
        comp.step(bad)
    got += [comp.step(v) for v in ref[1:]]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)  # state unchanged by the refused sample
    with pytest.raises(ModelError, match="must be finite"):
        comp.run([1.0, bad])


@pytest.mark.parametrize("limits", ["ab", (3.0,), 5.0, (1.0, float("nan")), (2.0, 1.0)])
def test_malformed_limits_one_line(limits):
    # compensate(m, y, limits="ab") raised a raw ValueError from float("a")
    m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    with pytest.raises(ModelError, match=r"`limits` must be \(low, high\)"):
        compensate(m, [0.0, 1.0], limits=limits)
    with pytest.raises(ModelError, match=r"`limits` must be \(low, high\)"):
        invert(m.to_modified(), [0.0, 1.0], limits=limits)


def _kernel_inversion(m, target):
    """The compiled batch inversion of ``m`` from zero state; its plain-Python twin's output."""
    from stageid.hysteresis import kernels
    from stageid.hysteresis.inverse.compensator import residual_bound
    from stageid.hysteresis.models.common import packed
    from stageid.hysteresis.models.operators import coupled_play_reference

    args = (target, packed(m), np.zeros(m.n_operators), 0.0, -np.inf, np.inf, m.min_slope(), *residual_bound(m))
    x, z, xf = kernels.cp_invert(*args)
    Z, zf = coupled_play_reference(x, *m.coupled_play_thresholds(), np.zeros(m.n_operators))
    return args, (x, z, xf), Z, zf


@pytest.mark.parametrize("seed", [0, 1])
def test_inversion_kernel_against_its_plain_python_twins(seed):
    # the compiled batch inversion equals its loop run by Python (``py_func``, which calls the
    # compiled per-sample step), and the inputs it finds drive the plain-Python CP bank (eq. 3-4,
    # no compiled code) onto the targets to the rounding bound the iteration stops at
    from stageid.hysteresis import kernels
    from stageid.hysteresis.inverse.compensator import residual_bound

    rng = np.random.default_rng(seed)
    m = _mpi(rng)
    target = np.cumsum(rng.normal(0.0, 8.0, 300))
    args, (x, z, xf), Z, zf = _kernel_inversion(m, target)
    x_py, z_py, xf_py = kernels.cp_invert.py_func(*args)
    np.testing.assert_array_equal(x, x_py)
    np.testing.assert_array_equal(z, z_py)
    assert xf == xf_py
    err_w, err_r = residual_bound(m)
    assert np.all(np.abs(Z @ m.weights - target) <= err_w * (np.abs(x) + err_r))
    np.testing.assert_array_equal(zf, z)


@pytest.mark.parametrize("seed", range(4))
def test_inversion_lands_on_the_exact_root(seed):
    # F is piecewise linear: the Newton step from the root's piece is the root, and the
    # iteration takes it instead of stopping at a tolerance.  The residual of the plain-Python
    # CP bank (its own in-order sum) at the inputs found is rounding: within the bound, and
    # below 1e-14 of the output scale sum|w| (|x| + max r) on every sample (the former
    # tolerance, 1e-12 of sum|w| (1 + max r), let single samples stop at ~1e-12).  The
    # references are random jumps over the whole range (many operators switch each sample), a
    # random walk, and targets off the model's own path.
    from stageid.hysteresis.inverse.compensator import residual_bound

    rng = np.random.default_rng(40 + seed)
    m = _mpi(rng, n=20)
    targets = {
        "jumps": m.simulate(rng.uniform(-450, 450, 4000))[:, 0] - m.output_offset,
        "walk": np.cumsum(rng.normal(0.0, 8.0, 4000)),
        "off-path": m.simulate(_drive(rng))[:, 0] + rng.normal(0, 0.5, 3000),
    }
    err_w, err_r = residual_bound(m)
    for name, target in targets.items():
        _, (x, _z, _xf), Z, _zf = _kernel_inversion(m, target)
        residual = np.abs(Z @ m.weights - target)
        scale = np.sum(np.abs(m.weights)) * (np.abs(x) + err_r)
        assert np.all(residual <= err_w * (np.abs(x) + err_r)), name
        assert np.max(residual / scale) < 1e-14, name


def test_inversion_exact_just_past_a_breakpoint():
    # analytic truth: on the initial loading curve of a PI model, F(x) = sum_i w_i (x - r_i)+ has
    # slope W_j = w_0 + ... + w_j on (r_j, r_j+1).  A target just past a corner, F(r_j) + d, has
    # the root r_j + d / W_j; the Newton step from the piece before the corner lands at
    # r_j + d / W_j-1, whose residual d (W_j / W_j-1 - 1) is below the former tolerance
    # (1e-12 of sum|w| (1 + max r), which stopped there: 1e-12 off in x) but not at rounding.
    # The iteration goes on to the root: within a few ulps of x.
    r = np.arange(12) * 3.0
    w = np.r_[1.0, np.linspace(0.2, 1.0, 11)]
    m = PIModel(r=r, weights=w).to_modified()
    d = 0.5 * 1e-12 * np.sum(w) * (1.0 + r.max())
    W = np.cumsum(w)
    loading = np.array([np.sum(w * np.maximum(rj - r, 0.0)) for rj in r])
    target = loading[1:] + d
    expected = r[1:] + d / W[1:]
    u, _ = invert(m, target)
    assert np.max(np.abs(u[:, 0] - expected)) <= 4 * np.spacing(r.max())
    comp = Compensator(m)
    assert np.max(np.abs([comp.step(v) - e for v, e in zip(target, expected)])) <= 4 * np.spacing(r.max())


@pytest.fixture(scope="module")
def piezo_model_and_record():
    from stageid.data import datasets
    from stageid.hysteresis import PIIdentifier

    root = datasets.shared_data_dir()
    if root is None or not (root / "piezo_dspace_preisach" / "prbn_1.mat").exists():
        pytest.skip("shared dSPACE piezo records not found")
    rec = datasets.load_dspace_piezo(root / "piezo_dspace_preisach" / "prbn_1.mat")
    model = PIIdentifier(model="modified-pi", n_operators=20).fit(rec).model
    return model, datasets.load_dspace_piezo(root / "piezo_dspace_preisach" / "sine100_1.mat")


def test_inversion_exact_on_a_measured_reference(piezo_model_and_record):
    # the model identified on the dSPACE PRBN record (input warp, near-zero and negative weights:
    # its slope can drop to 7e-4 of its largest weight) asked for the displacement measured on
    # another record: where no limit is hit the model reproduces it to rounding, through the
    # input warp and back (a few 1e-15 of the largest displacement; 1e-14 leaves room)
    model, rec = piezo_model_and_record
    y = rec.y[:, 0]
    u = Compensator(model).run(y)[:, 0]
    lo, hi = model.input_limits
    free = (u > lo) & (u < hi)
    assert free.mean() > 0.9
    residual = np.abs(model.simulate(u)[:, 0] - y)[free]
    assert residual.max() <= 1e-14 * np.abs(y).max()
    np.testing.assert_array_equal(invert(model, y)[0][:, 0], u)


@pytest.mark.parametrize("make", [_pi, _mpi])
def test_invert_respects_limits_on_both_sides(make):
    # the outputs of a drive asked through limits at its 10th and 90th percentiles: both limits
    # are hit, the inputs never leave them, and wherever no limit is hit the model reproduces y
    # (the docstring's promise)
    rng = np.random.default_rng(5)
    m = make(rng)
    drive = _drive(rng)
    yd = m.simulate(drive)[:, 0]
    lo, hi = (float(v) for v in np.percentile(drive, [10, 90]))
    u, state = invert(m, yd, limits=(lo, hi))
    u = u[:, 0]
    assert u.min() == lo and u.max() == hi
    inside = (u > lo) & (u < hi)
    assert 0.2 < inside.mean() < 0.95  # both saturated and free stretches
    y = m.simulate(u)[:, 0]
    # 1e-9 of the output scale: the per-sample inverse is exact to its 1e-12 tolerance
    np.testing.assert_allclose(y[inside], yd[inside], rtol=0, atol=1e-9 * np.abs(yd).max())
    np.testing.assert_allclose(state.z, m.run(u)[1].z, rtol=0, atol=1e-9 * np.abs(yd).max())
    # the model's own input_limits are the default
    u2, _ = invert(dataclasses.replace(m, input_limits=(lo, hi)), yd)
    np.testing.assert_array_equal(u2[:, 0], u)


def test_closed_form_inverse_needs_every_loading_slope_positive():
    # slopes cumsum(w) = [1, 0, 0.5] and [1, -0.5, 0.5]: a zero slope is already not invertible
    for w in ([1.0, -1.0, 0.5], [1.0, -1.5, 1.0]):
        with pytest.raises(ModelError, match=r"not invertible: initial-loading slope 1 is"):
            pi_inverse(PIModel(r=[0.0, 1.0, 2.0], weights=w))
    assert pi_inverse(PIModel(r=[0.0, 1.0, 2.0], weights=[1.0, -0.9, 0.5])).weights[0] == 1.0


def warped_model_of_a_measured_record() -> ModifiedPIModel:
    """Limits and warp of a model identified on a measured record: mapped back through the
    warp, the operator-side limit comes out 1e-13 inside the drive limit, where a drive would
    read as one that hit no limit while the model's output falls short of the target."""
    R = 84.77249999999965
    r = np.arange(5) * R / 5
    model = ModifiedPIModel(
        r=r, rc=r, ra=1.08 * r, rb=1.05 * r, weights=np.array([0.02, 0.01, -0.002, 0.004, 0.002]),
        input_warp=-0.023127473106766404, warp_scale=R, input_offset=-13.147300615777679,
        input_limits=(-100.1249999999992, 69.4200000000001),
    )  # fmt: skip
    return model.with_state(model.consistent_state(0.0, "zero"))


def test_a_warped_drive_at_its_limit_is_the_limit_itself():
    model = warped_model_of_a_measured_record()
    lo, hi = model.input_limits
    assert Compensator(model).run([0.0, 5.0, 10.0])[-1, 0] == hi
    comp = Compensator(model)
    assert [comp.step(v) for v in (0.0, 5.0, 10.0)][-1] == hi
    assert Compensator(model).run([0.0, -5.0, -10.0])[-1, 0] == lo
    assert invert(model, [0.0, 5.0, 10.0])[0][-1, 0] == hi
