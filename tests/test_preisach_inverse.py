"""Exact inverse of the continuous-cell Preisach model: round trips, memory, limits, bad input, CLI."""

import numpy as np
import pytest

from conftest import assert_one_line_error, run_main
from stageid import ModelError
from stageid.hysteresis.inverse.preisach import PreisachCompensator, preisach_feedforward
from stageid.hysteresis.models.preisach import PreisachModel
from stageid.models.serialization import dumps


def _model(seed, n=9, zeros=0.0):
    rng = np.random.default_rng(seed)
    w = rng.random(n * (n + 1) // 2)
    w[rng.random(w.size) < zeros] = 0.0  # flat stretches of the output (zero-weight cells)
    m = PreisachModel((-2.0, 3.0), w, output_offset=rng.standard_normal())
    return m.with_state(m.consistent_state(rng.uniform(-2.0, 3.0)))


def _reachable(m, seed, n=3000, jumps=False):
    """Desired outputs strictly inside the model's output range (every one is reachable)."""
    rng = np.random.default_rng(seed)
    total = float(m.weights.sum())
    if jumps:
        rel = rng.uniform(0.001, 0.999, n)
    else:
        rel = 0.5 + np.cumsum(rng.standard_normal(n)) * 0.05
        rel = 0.001 + np.abs((rel - 0.001) % (2 * 0.998) - 0.998)  # reflected into (0, 1)
    return m.output_offset + total * rel, total


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("jumps", [False, True])
@pytest.mark.parametrize("zeros", [0.0, 0.4])
def test_model_of_the_drive_is_the_reference_to_rounding(seed, jumps, zeros):
    m = _model(seed, zeros=zeros)
    y, total = _reachable(m, seed + 100, jumps=jumps)
    u = preisach_feedforward(m, y, limits=(-np.inf, np.inf))
    # one linear interpolation per sample: a few ulps of the output scale
    np.testing.assert_allclose(m.simulate(u)[:, 0], y, rtol=0, atol=1e-13 * total)
    assert np.all((u >= -2.0) & (u <= 3.0))


def test_streaming_steps_blocks_and_batch_agree_and_the_memory_is_the_models():
    m = _model(5)
    y, _ = _reachable(m, 7, n=600)
    batch = preisach_feedforward(m, y)[:, 0]
    comp = PreisachCompensator(m)
    steps = np.array([comp.step(v) for v in y[:200]])
    block = comp.run(y[200:])[:, 0]
    np.testing.assert_array_equal(np.r_[steps, block], batch)
    # the compensator's memory is what the model reaches on the drive
    np.testing.assert_array_equal(comp.state, m.run(batch)[1])
    comp.reset()
    np.testing.assert_array_equal(comp.run(y)[:, 0], batch)


def test_the_drive_is_the_smallest_move_where_the_output_is_flat():
    m = PreisachModel((0.0, 4.0), [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # one square
    # cell alpha in [2, 3], beta in [1, 2]: below alpha 2 the rising output is flat at 0
    u = preisach_feedforward(m, [0.0, 0.5, 1.0, 1.0, 0.5])[:, 0]
    np.testing.assert_allclose(u, [0.0, 2.5, 3.0, 3.0, 1.5], atol=1e-15)


def test_drive_limits_clip_and_the_memory_follows_the_clipped_drive():
    m = _model(8)
    y, total = _reachable(m, 9, n=800)
    lim = (-1.0, 2.0)
    comp = PreisachCompensator(m, limits=lim)
    u = comp.run(y)[:, 0]
    assert u.min() >= lim[0] and u.max() <= lim[1]
    assert np.any(u == lim[0]) and np.any(u == lim[1])  # the reference asks for more
    miss = np.abs(m(u) - y) > 1e-13 * total
    assert np.all((u[miss] == lim[0]) | (u[miss] == lim[1]))  # exact wherever it is not clipped
    np.testing.assert_array_equal(comp.state, m.run(u)[1])


def test_unreachable_outputs_saturate_at_the_grid_ends():
    m = _model(10)
    total = float(m.weights.sum())
    u = preisach_feedforward(m, m.output_offset + np.array([2 * total, -total, 0.5 * total]))[:, 0]
    assert u[:2].tolist() == [3.0, -2.0]
    assert m(u)[2] == pytest.approx(m.output_offset + 0.5 * total, abs=1e-13 * total)


def test_default_limits_are_the_models_input_limits():
    m = _model(11)
    m = PreisachModel(m.input_range, m.weights, m.output_offset, m.state, input_limits=(0.0, 1.0))
    y, _ = _reachable(m, 12, n=300)
    u = preisach_feedforward(m, y)[:, 0]
    assert u.min() >= 0.0 and u.max() <= 1.0


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_reference_is_one_line_and_leaves_the_memory(bad):
    comp = PreisachCompensator(_model(12))
    comp.run([0.1, 0.2])
    before = comp.state.copy()
    with pytest.raises(ModelError) as info:
        comp.run([0.3, bad])
    assert "\n" not in str(info.value)
    np.testing.assert_array_equal(comp.state, before)


def test_negative_weights_and_bad_limits_are_refused():
    with pytest.raises(ModelError, match="not monotone"):
        PreisachCompensator(PreisachModel((0.0, 1.0), [1.0, -0.5, 1.0]))
    with pytest.raises(ModelError, match="low < high"):
        PreisachCompensator(_model(13), limits=(1.0, 0.0))


def _files(tmp_path, m, y):
    (tmp_path / "m.json").write_text(dumps(m.to_dict()))
    t = np.arange(len(y)) * 1e-3
    np.savetxt(tmp_path / "ref.csv", np.c_[t, y], delimiter=",", header="t,yref", comments="")


def test_cli_compensate_writes_the_exact_drive(tmp_path):
    m = _model(14)
    y, total = _reachable(m, 15, n=500)
    _files(tmp_path, m, y)
    args = ["compensate", tmp_path / "m.json", tmp_path / "ref.csv", "--column", "yref"]
    rc, _, err = run_main(*args, "--limits", "-2,3", "-o", tmp_path / "u.csv")
    assert rc == 0, err
    u = np.loadtxt(tmp_path / "u.csv", delimiter=",", skiprows=1)[:, 1]
    np.testing.assert_allclose(m(u), y, rtol=0, atol=1e-12 * total)  # through the drive file


def test_cli_compensate_bad_reference_is_one_line_exit_2_no_file(tmp_path):
    m = _model(16)
    y, _ = _reachable(m, 17, n=50)
    y[20] = np.nan
    _files(tmp_path, m, y)
    args = ["compensate", tmp_path / "m.json", tmp_path / "ref.csv", "--column", "yref"]
    rc, _, err = run_main(*args, "-o", tmp_path / "u.csv")
    assert_one_line_error(rc, err)
    assert not (tmp_path / "u.csv").exists()
