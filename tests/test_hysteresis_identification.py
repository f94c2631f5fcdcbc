"""Identification: exact recovery where the model class contains the truth, constraints, offsets."""

import numpy as np
import pytest

from stageid import DataError, ParameterError
from stageid.hysteresis import ModifiedPIModel, PIIdentifier, PIModel, align_record
from stageid.signals import decaying_triangle


def _input():
    return decaying_triangle(1.0, 8, 2e-3, amplitude=400.0)


def test_recovers_classical_pi_exactly():
    u = _input()
    r = np.arange(8) * 50.0  # the grid PIIdentifier uses for +-400 V and 8 operators
    true = PIModel(r=r, weights=[0.01, 0.004, 0.003, -0.001, 0.002, 0.001, 0.0015, 0.0005])
    fit = PIIdentifier("pi", n_operators=8).fit((u, true.simulate(u)))
    np.testing.assert_allclose(fit.model.weights, true.weights, atol=1e-9)
    assert fit.max_error_percent[0] < 1e-6
    assert np.all(fit.model.initial_loading_slopes() > 0)


def test_recovers_modified_pi_on_the_search_grid():
    u = _input()
    r = np.arange(8) * 50.0
    true = ModifiedPIModel(
        r=r, rc=0.5 * r, ra=1.4 * r, rb=0.7 * 1.4 * r, weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005]
    )
    y = true.simulate(u)
    classical = PIIdentifier("pi", n_operators=8).fit((u, y))
    fit = PIIdentifier("modified-pi", n_operators=8, max_evaluations=200, input_warp=False).fit((u, y))
    assert classical.max_error_percent[0] > 2.0  # the CP asymmetry is not a PI model
    assert fit.max_error_percent[0] < 0.05
    assert fit.model.min_slope() > 0 and fit.model.input_warp == 0.0


def test_recovers_input_warp():
    u = _input()
    r = np.arange(8) * 50.0
    true = ModifiedPIModel(
        r=r,
        rc=0.5 * r,
        ra=1.4 * r,
        rb=0.7 * 1.4 * r,
        input_warp=0.2,
        warp_scale=400.0,
        weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005],
    )
    y = true.simulate(u)
    without = PIIdentifier("modified-pi", n_operators=8, max_evaluations=200, input_warp=False).fit((u, y))
    fit = PIIdentifier("modified-pi", n_operators=8, max_evaluations=200).fit((u, y))
    assert without.max_error_percent[0] > 1.0
    assert fit.max_error_percent[0] < 0.05
    assert abs(fit.model.input_warp - 0.2) < 1e-3


def test_offsets_per_record_and_starting_state():
    u = _input()
    true = PIModel(r=np.arange(8) * 50.0, weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005])
    y = true.simulate(u)[:, 0]
    # second record: other sensor zero, starts at -100 V having come up from below
    u2 = np.r_[np.linspace(-100, -50, 100), np.linspace(-50, -300, 300), np.linspace(-300, 100, 200)]
    start = true.with_state(true.consistent_state(-100.0, "ascending"))
    y2 = start.simulate(u2)[:, 0] + 1.7
    fit = PIIdentifier("pi", n_operators=8).fit([(u, y + 0.2), (u2, y2)])
    assert fit.initial_states == ("zero", "ascending")
    np.testing.assert_allclose(fit.output_offsets, [0.2, 1.7], atol=1e-9)
    _, yh = align_record(fit.model, u2, y2)
    np.testing.assert_allclose(yh[:, 0], y2, atol=1e-7)  # weights from a least-squares solve: ~1e-10 each, times 400 V


def test_monotone_constraint_active():
    # data that would need a falling branch: the constrained weights keep every slope >= eps
    u = _input()
    y = np.sin(u / 60.0)  # not monotone in u at all
    fit = PIIdentifier("pi", n_operators=10).fit((u, y))
    eps = 0.02 * np.ptp(y) / np.ptp(u)
    assert np.all(fit.model.initial_loading_slopes() >= eps * (1 - 1e-9))
    fit2 = PIIdentifier("modified-pi", n_operators=10, max_evaluations=40).fit((u, y))
    assert fit2.model.min_slope() >= eps * (1 - 1e-6)


def test_bad_hyperparameters():
    u = _input()
    with pytest.raises(ParameterError, match="model"):
        PIIdentifier("preisach").fit((u, u))
    with pytest.raises(ParameterError, match="n_operators"):
        PIIdentifier("pi", n_operators=1).fit((u, u))


@pytest.mark.parametrize("input_range", [(-270.0, 90.0), (-90.0, 270.0)])
def test_classical_fit_with_input_range_wider_than_the_data(input_range):
    # operators whose thresholds lie beyond the data never move: their columns are collinear
    # with the offset, the Gram matrix of the bounded fit is singular to rounding (this raised
    # numpy's LinAlgError "Matrix is not positive definite" before)
    from stageid.signals import forc_staircase

    u = forc_staircase(-90, 90, 50, 20, 1e-4, shape="cosine")
    r = np.arange(8) * 90 / 8
    true = ModifiedPIModel(
        r=r, rc=0.5 * r, ra=1.4 * r, rb=0.7 * 1.4 * r, weights=[0.01, 0.004, 0.003, 0.002, 0.002, 0.001, 0.0015, 0.0005]
    )
    y = true.simulate(u)[:, 0] + 1e-4 * np.random.default_rng(0).standard_normal(u.size)
    narrow = PIIdentifier("pi", n_operators=20).fit((u, y))
    fit = PIIdentifier("pi", n_operators=40, input_range=input_range).fit((u, y))
    assert np.all(fit.model.initial_loading_slopes() > 0)
    # 20 of the 40 operators cover the data's range: about as good as 20 over the range itself
    assert fit.max_error_percent[0] < 1.2 * narrow.max_error_percent[0]


# --- regressions of the bug hunt (each failed before its fix) --------------------------------


def _small():
    u = decaying_triangle(1.0, 4, 2e-3, amplitude=100.0)  # 2000 samples
    true = PIModel(r=np.arange(4) * 25.0, weights=[0.01, 0.004, 0.003, 0.002])
    return u, true.simulate(u)[:, 0]


def test_flat_output_record_refused_per_record():
    # a constant second record used to give "inf %" errors and RuntimeWarnings
    u, y = _small()
    with pytest.raises(DataError, match=r"record 1: the output is constant \(1\.5\)"):
        PIIdentifier("pi", n_operators=4).fit([(u, y), (u, np.full(u.size, 1.5))])


def test_two_input_columns_refused():
    u, y = _small()
    with pytest.raises(DataError, match=r"record 0: one input column expected .*got shape \(2000, 2\)"):
        PIIdentifier("pi", n_operators=4).fit((np.c_[u, u], y))
    with pytest.raises(DataError, match=r"one output column expected .*got shape \(2000, 3\)"):
        PIIdentifier("pi", n_operators=4).fit((u, np.c_[y, y, y]))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(max_rows=0), "`max_rows` of PIIdentifier must be an integer >= 10; got 0"),
        (dict(max_rows=2.5), "`max_rows`"),
        (dict(min_slope_fraction="x"), r"`min_slope_fraction` of PIIdentifier must be a number in \(0, 1\); got 'x'"),
        (dict(min_slope_fraction=float("nan")), "`min_slope_fraction`"),
        (
            dict(input_range=(10, -10)),
            r"`input_range` of PIIdentifier must be \(low, high\) with finite low < high or None; got \(10, -10\)",
        ),
        (dict(input_range=(10,)), "`input_range`"),
        (dict(input_range="ab"), "`input_range`"),
        (dict(ridge=-1.0), "`ridge`"),
        (dict(max_evaluations=0), "`max_evaluations`"),
        (dict(input_warp="no"), "`input_warp`"),
        (dict(sample_time=-1e-3), "`sample_time`"),
        (dict(n_operators=5000), "`n_operators` of PIIdentifier must be at most 1000 for a pi model; got 5000"),
        (dict(model="modified-pi", n_operators=101), "at most 100 for a modified-pi model; got 101"),
    ],
)
def test_bad_hyperparameters_one_line(kwargs, match):
    # raw ZeroDivisionError / ValueError or misleading messages before
    u, y = _small()
    kwargs = {"model": "pi", "n_operators": 4, **kwargs}
    with pytest.raises(ParameterError, match=match) as info:
        PIIdentifier(**kwargs).fit((u, y))
    assert "\n" not in str(info.value)


def test_n_operators_bounded_by_the_records():
    u, y = _small()
    u, y = u[:200], y[:200]  # 200 samples: one operator per 5 samples, 40 at most
    PIIdentifier("pi", n_operators=4).fit((u, y))
    with pytest.raises(ParameterError, match="at most 40 for these records .* got 41"):
        PIIdentifier("pi", n_operators=41).fit((u, y))
    steps = np.repeat([0.0, 50.0, -50.0, 100.0, -100.0, 0.0], 20)  # 5 distinct input values
    with pytest.raises(ParameterError, match="their 5 distinct input values\\); got 6"):
        PIIdentifier("pi", n_operators=6).fit((steps, 0.01 * steps))


def test_identified_model_records_its_input_range():
    # input_limits were always None, so the compensator never kept to the identified range
    from stageid.hysteresis import compensate
    from stageid.models.serialization import dumps, loads

    u, y = _small()
    u2 = 0.5 * u - 30.0
    fit = PIIdentifier("pi", n_operators=4).fit(
        [(u, y), (u2, PIModel(r=np.arange(4) * 25.0, weights=[0.01, 0.004, 0.003, 0.002]).simulate(u2))]
    )
    assert fit.model.input_limits == (float(u.min()), float(u.max()))
    assert loads(dumps(fit.model.to_dict())).input_limits == fit.model.input_limits
    drive = compensate(fit.model, 100.0 * y)  # 100x the identified output range
    assert drive.min() >= u.min() and drive.max() <= u.max()
    mpi = PIIdentifier("modified-pi", n_operators=4, max_evaluations=5, input_range=(-200.0, 200.0)).fit((u, y))
    assert mpi.model.input_limits == (float(u.min()), float(u.max()))  # the data's range, not input_range
