"""API robustness: arx/pem refuse a constant input and a bad ``dt``; Experiment.slice takes
integral sample indices of any numeric type; plant experiments refuse bad seeds.

Every refusal is a one-line stageid error naming what was expected and what came, and the
caller's arrays are left as they were.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as ss

from stageid._errors import DataError, IdentificationError, SignalError, StageIdError
from stageid.closedloop import arx, pem, select_order
from stageid.data import Experiment
from stageid.plants import PLANTS, plant_module


def _one_line(exc: pytest.ExceptionInfo) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def _io(n: int = 600, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    u = np.random.default_rng(seed).standard_normal(n)
    return u, ss.lfilter([0.0, 0.3, 0.1], [1.0, -1.2, 0.5], u)


# ------------------------------------------------------------- pem: constant input
FITS = {
    "arx": lambda u, y, **kw: arx(u, y, 2, 2, **kw),
    "pem-arx": lambda u, y, **kw: pem(u, y, "arx", {"na": 2, "nb": 2}, **kw),
    "pem-armax": lambda u, y, **kw: pem(u, y, "armax", {"na": 1, "nb": 1, "nc": 1}, **kw),
    "pem-oe": lambda u, y, **kw: pem(u, y, "oe", {"nb": 2, "nf": 2}, **kw),
    "pem-bj": lambda u, y, **kw: pem(u, y, "bj", {"nb": 1, "nf": 1, "nc": 1, "nd": 1}, **kw),
    "select_order-oe": lambda u, y, **kw: select_order(u, y, "oe", orders=[1, 2, 3, 4], **kw),
    "select_order-arx": lambda u, y, **kw: select_order(u, y, "arx", orders=[1, 2], **kw),
}


@pytest.mark.parametrize("fit", list(FITS))
@pytest.mark.parametrize("level", [1.5, -2.0])
def test_constant_nonzero_input_is_refused(fit: str, level: float) -> None:
    # before: arx/pem/select_order returned a model fitted to the step from the zeros
    # assumed before the record, without a word
    _, y = _io()
    u = np.full(y.size, level)
    with pytest.raises(IdentificationError, match="must move") as exc:
        FITS[fit](u, y)
    msg = _one_line(exc)
    assert f"constant at {level:g}" in msg and "1 record(s)" in msg


def test_constant_input_in_every_record_is_refused_but_one_moving_record_suffices() -> None:
    u, y = _io(400)
    c1, c2 = np.full(400, 3.0), np.full(400, -1.0)
    with pytest.raises(IdentificationError, match=r"zero range \(constant\) in all 2 record\(s\)"):
        pem([c1, c2], [y, y], "oe", {"nb": 2, "nf": 2})
    m = pem([c1, u], [y, y], "oe", {"nb": 2, "nf": 2})  # the second record excites the model
    assert m.n_samples == 800


def test_zero_input_still_raises_identification_error() -> None:
    _, y = _io()
    with pytest.raises(IdentificationError, match="zero range"):
        arx(np.zeros(y.size), y, 2, 2)


# ------------------------------------------------------------- pem: dt
@pytest.mark.parametrize("fit", list(FITS))
@pytest.mark.parametrize("dt", [0, 0.0, -1e-3, float("nan"), float("inf"), "0.001", True, None])
def test_bad_dt_is_refused(fit: str, dt: object) -> None:
    u, y = _io()
    with pytest.raises(DataError, match="`dt` must be a positive, finite number of seconds") as exc:
        FITS[fit](u, y, dt=dt)
    assert _one_line(exc).endswith(f"got {dt!r}.")


@pytest.mark.parametrize("dt", [2e-4, np.float32(0.5), 3])
def test_good_dt_is_stored_as_float(dt: object) -> None:
    u, y = _io()
    for m in (arx(u, y, 2, 2, dt=dt), pem(u, y, "oe", {"nb": 2, "nf": 2}, dt=dt)):
        assert type(m.dt) is float and m.dt == float(dt)


def test_pem_paths_leave_the_callers_arrays_alone() -> None:
    u, y = _io()
    c = np.full(y.size, 2.0)
    arrays = [u, y, c]
    before = [a.copy() for a in arrays]
    arx(u, y, 2, 2)
    pem(u, y, "oe", {"nb": 2, "nf": 2})
    for call in (
        lambda: arx(c, y, 2, 2),
        lambda: pem(c, y, "oe", {"nb": 2, "nf": 2}),
        lambda: arx(u, y, 2, 2, dt=0.0),
        lambda: select_order(c, y, "oe", orders=[1, 2, 3, 4]),
    ):
        with pytest.raises(StageIdError):
            call()
    for a, b in zip(arrays, before):
        np.testing.assert_array_equal(a, b)
        assert a.flags.writeable


# ------------------------------------------------------------- Experiment.slice
def _exp(n: int = 10) -> Experiment:
    return Experiment(u=np.arange(float(n)), y=10.0 * np.arange(float(n)), dt=0.5, t0=100.0)


@pytest.mark.parametrize(
    "start, stop", [(2.0, 6), (2, 6.0), (np.int64(2), 6.0), (np.float64(2.0), np.int32(6)), (2, np.uint8(6))]
)
def test_slice_takes_integral_indices_of_any_numeric_type(start: object, stop: object) -> None:
    # before: any float (even 2.0) raised a raw TypeError from numpy indexing
    part = _exp().slice(start, stop)
    np.testing.assert_array_equal(part.u[:, 0], [2.0, 3.0, 4.0, 5.0])
    np.testing.assert_array_equal(part.y[:, 0], [20.0, 30.0, 40.0, 50.0])
    assert part.t0 == 100.0 + 2 * 0.5


def test_slice_stop_none_runs_to_the_end() -> None:
    part = _exp().slice(7.0)
    np.testing.assert_array_equal(part.u[:, 0], [7.0, 8.0, 9.0])


@pytest.mark.parametrize("start, stop, bad", [(1.5, 4, "start"), (1, 4.25, "stop"), (1.5, 4.0, "start")])
def test_slice_refuses_fractional_indices_and_says_they_are_samples(start: object, stop: object, bad: str) -> None:
    with pytest.raises(DataError, match=f"`{bad}` of Experiment.slice must be an integer sample index in 0..10") as exc:
        _exp().slice(start, stop)
    msg = _one_line(exc)
    assert f"got {start if bad == 'start' else stop!r}" in msg and "round((t - t0) / dt)" in msg


@pytest.mark.parametrize(
    "start, stop", [("1", 4), (0, "4"), (None, 4), (True, 4), (0, float("nan")), (0, float("inf")), ([1], 4)]
)
def test_slice_refuses_non_numeric_indices(start: object, stop: object) -> None:
    with pytest.raises(DataError, match="must be an integer sample index") as exc:
        _exp().slice(start, stop)
    msg = _one_line(exc)
    assert repr(start) in msg or repr(stop) in msg


@pytest.mark.parametrize("start, stop", [(6, 2), (4, 4), (-1, 4), (0, 11), (10, None), (3.0, 2.0), (0.0, 11.0)])
def test_slice_refuses_reversed_empty_or_out_of_range(start: object, stop: object) -> None:
    with pytest.raises(DataError, match=r"0 <= start < stop <= 10; got start=") as exc:
        _exp().slice(start, stop)
    _one_line(exc)


def test_slice_copies_and_leaves_the_callers_arrays_alone() -> None:
    u, y = np.arange(10.0), np.arange(10.0) ** 2
    u0, y0 = u.copy(), y.copy()
    exp = Experiment(u=u, y=y, dt=0.1)
    part = exp.slice(2.0, 5)
    with pytest.raises(DataError):
        exp.slice(1.5, 5)
    assert not np.shares_memory(part.u, exp.u) and not part.u.flags.writeable
    np.testing.assert_array_equal(u, u0)
    np.testing.assert_array_equal(y, y0)
    assert u.flags.writeable and y.flags.writeable


# ------------------------------------------------------------- plant experiment seeds
ALL_EXPERIMENTS = [(p, e) for p in PLANTS for e in plant_module(p).EXPERIMENTS]


@pytest.mark.parametrize("plant, experiment", ALL_EXPERIMENTS)
@pytest.mark.parametrize("seed", [-1, 1.5, 2.0, "3", True, None, np.int64(-4)])
def test_plant_experiments_refuse_bad_seeds(plant: str, experiment: str, seed: object) -> None:
    # before: numpy's ValueError/TypeError for -1 and 1.5, and "3", 2.0, True, None accepted
    # by some builders (the piezo actuator ignored its seed entirely when noise-free)
    f = plant_module(plant).EXPERIMENTS[experiment]
    with pytest.raises(SignalError, match=f"`seed` of plant experiment '{experiment}' must be an integer >= 0") as exc:
        f(seed=seed)
    assert _one_line(exc).endswith(f"got {seed!r}.")


@pytest.mark.parametrize(
    "plant, experiment", [("p558", "random-z"), ("p558", "prbs"), ("piezo-actuator", "triangle-1hz")]
)
def test_plant_experiments_accept_numpy_integer_seeds(plant: str, experiment: str) -> None:
    f = plant_module(plant).EXPERIMENTS[experiment]
    a, b = f(seed=np.int64(5)), f(seed=5)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.y, b.y)


@pytest.mark.parametrize("axis", ["z", "", None, 3])
def test_maglev_chirp_axis_is_checked_in_one_line(axis):
    from stageid._errors import SignalError
    from stageid.plants import maglev

    with pytest.raises(SignalError, match=r"`axis` of the maglev chirp must be one of x, y, phi; got") as info:
        maglev.simulate_chirp(axis)
    assert "\n" not in str(info.value)
