"""The sample-time rule (stageid.data.sampling): periods read from time columns as loggers write
them, records compared with one tolerance, bad periods refused in one line."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from stageid import DataError
from stageid.data import Experiment, as_experiments, read_table
from stageid.data.sampling import (
    MAX_PERIOD,
    MIN_PERIOD,
    PERIOD_RTOL,
    UNIFORM_RTOL,
    check_period,
    same_period,
    shared_period,
    time_grid,
)

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks" / "recovery"))
from common import TIME_STYLES, time_column  # noqa: E402


def _stamps(n: int, fs: float, style: str) -> np.ndarray:
    return np.array([float(v) for v in time_column(n, fs, style, np.random.default_rng(n))])


def _old_mean_step(t: np.ndarray) -> float:
    """The period every reader took before: (t[-1] - t[0]) / (n - 1)."""
    return float(t[-1] - t[0]) / (t.shape[0] - 1)


@pytest.mark.parametrize("style", TIME_STYLES)
@pytest.mark.parametrize("fs", [10000.0, 3000.0, 7000.0])
@pytest.mark.parametrize("n", [24000, 4988, 200])
def test_period_of_every_logger_style(style, fs, n):
    grid = time_grid(_stamps(n, fs, style))
    # 1e-9: what the brief of the rule asks; the simplest-period step makes these exact
    assert grid.dt == pytest.approx(1.0 / fs, rel=1e-9, abs=0)
    assert grid.jitter < 1e-5  # rounding (and accumulated sums) is not jitter


def test_repr_column_of_unequal_lengths_has_one_period():
    # the two lengths of the failing report: the old mean step differs by an ulp between them
    a, b = _stamps(24000, 1e4, "repr"), _stamps(4988, 1e4, "repr")
    assert _old_mean_step(a) != _old_mean_step(b)
    assert time_grid(a).dt == time_grid(b).dt == 1e-4


def test_periods_a_relative_1e4_apart_are_refused_with_distinct_digits():
    exps = [Experiment(np.ones(5), np.ones(5), 1e-4, name="a"), Experiment(np.ones(5), np.ones(5), 1.0001e-4, name="b")]
    with pytest.raises(DataError) as info:
        as_experiments(exps)
    message = str(info.value)
    assert "0.0001 s (a)" in message and "0.00010001 s (b)" in message
    assert f"{PERIOD_RTOL:g}" in message  # the tolerance is printed


@pytest.mark.parametrize("apart", [1e-4, 1e-5, 2e-6])
def test_periods_beyond_the_tolerance_are_refused(apart):
    with pytest.raises(DataError, match="must share one sample time"):
        shared_period([1e-4, 1e-4 * (1 + apart)])


@pytest.mark.parametrize("apart", [1, 3])  # ulps
def test_periods_ulps_apart_are_accepted_and_shared(apart):
    dt = 1e-4
    other = dt
    for _ in range(apart):
        other = float(np.nextafter(other, 1.0))
    exps = as_experiments([Experiment(np.ones(5), np.ones(5), dt), Experiment(np.ones(5), np.ones(5), other)])
    assert [e.dt for e in exps] == [dt, dt]


def test_period_tolerance_is_stated_between_rounding_and_clock_differences():
    # pinned from both sides: float32 stamps leave ~1e-9, two clocks differ by >= 1e-4
    assert same_period(1e-4, 1e-4 * (1 + 5e-7))
    assert not same_period(1e-4, 1e-4 * (1 + 2e-6))
    assert 5e-7 <= PERIOD_RTOL < 2e-6


def test_hysteresis_creep_period_shared_by_ulp_apart_records():
    from stageid.hysteresis.identify.records import sampling_period

    u = np.sin(np.linspace(0, 6, 50))
    exps = [Experiment(u, u, 1e-4), Experiment(u, u, 9.999999999999999e-05)]
    assert sampling_period(exps, None) == 1e-4
    with pytest.raises(DataError, match="must share one sample time"):
        sampling_period([Experiment(u, u, 1e-4), Experiment(u, u, 1.0001e-4)], None)


def _jittered(n: int, dt: float, row: int, offset: float) -> np.ndarray:
    t = dt * np.arange(n)
    t[row] += offset * dt
    return t


def test_jitter_within_the_tolerance_is_accepted_and_measured():
    grid = time_grid(_jittered(1000, 1e-3, 400, 5e-4))
    assert grid.dt == 1e-3
    assert grid.jitter == pytest.approx(5e-4, rel=0.01)


def test_jitter_beyond_the_tolerance_is_refused_with_the_tolerance():
    with pytest.raises(
        DataError, match=r"not uniform: the stamp at row 400 .* lies 0\.002 periods off .* within 0\.001 of the period"
    ):
        time_grid(_jittered(1000, 1e-3, 400, 2e-3))
    assert 5e-4 < UNIFORM_RTOL < 2e-3


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: np.delete(t, 300), r"has a gap at row 300 "),  # a lost sample
        (lambda t: np.insert(t, 300, t[299]), r"must be strictly increasing; row 300 has"),  # a repeat
        (lambda t: np.concatenate([t[:300], t[298:299], t[300:]]), r"must be strictly increasing; row 300 has"),
    ],
)
def test_gaps_repeats_and_reversals_are_refused_with_their_row(edit, message):
    with pytest.raises(DataError, match=message):
        time_grid(edit(1e-3 * np.arange(1000)))


@pytest.mark.parametrize("scale", [1e-320, 1e-300, 1e300, 1e13])
def test_time_columns_with_periods_out_of_range_are_refused(scale):
    with pytest.raises(DataError, match=r"must be a period between 1e-15 s and 1e\+12 s"):
        time_grid(np.arange(100) * scale)


@pytest.mark.parametrize("value", [1e-320, 0.0, -1e-3, float("inf"), float("nan"), 1e300, "x"])
def test_bad_periods_are_refused_in_one_line(value):
    for check in (
        lambda: check_period(value),
        lambda: Experiment(np.ones(3), np.ones(3), value),
    ):
        with pytest.raises(DataError) as info:
            check()
        assert "\n" not in str(info.value)
    assert check_period(MIN_PERIOD) == MIN_PERIOD and check_period(MAX_PERIOD) == MAX_PERIOD


def test_read_table_ts_is_checked_against_the_column_with_the_period_tolerance(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("t,u\n" + "".join(f"{float(v)!r},1\n" for v in np.arange(100) / 1e4))
    assert read_table(path, ts=1e-4).dt == 1e-4
    with pytest.raises(DataError, match=r"ts=0\.00010001 s disagrees with the period 0\.0001 s .*1e-06"):
        read_table(path, ts=1.0001e-4)
    for bad in (1e-320, float("inf")):
        with pytest.raises(DataError, match="`ts` must be"):
            read_table(path, ts=bad)
