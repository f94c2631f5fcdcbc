"""Tests that kill surviving mutants of ``hysteresis/identification.py`` (tests/MUTATION.md).

The resource guards, the operator caps and the summary's ratios only matter at their limits
or in text, which the recovery tests never reach: these tests sit exactly on them.
"""

from __future__ import annotations

import numpy as np
import pytest

from stageid import ParameterError, ResourceError
from stageid.hysteresis import ModifiedPIModel, PIIdentifier, PIModel
from stageid.hysteresis.identify import pi as ident
from stageid.hysteresis.identify.pi import HysteresisFit


class _Stop(Exception):
    """Raised by the recording guard so that no fit runs after the cost check."""


def _records(n1: int = 1000, n2: int = 1001) -> list[tuple[np.ndarray, np.ndarray]]:
    true = PIModel(r=np.arange(4) * 25.0, weights=[0.01, 0.004, 0.003, 0.002])
    out = []
    for n, phase in ((n1, 0.0), (n2, 0.3)):
        u = 100.0 * np.sin(np.linspace(0, 6 * np.pi, n) + phase)
        out.append((u, true.simulate(u)[:, 0]))
    return out


def _costs(monkeypatch: pytest.MonkeyPatch, est: PIIdentifier, recs) -> tuple[float, float]:
    """(bytes, operations) the fit asks the resource guards for."""
    seen = {}

    def memory(n_bytes, what):
        seen["bytes"] = n_bytes

    def work(n_ops, limit, what, hint):
        seen["ops"], seen["limit"] = n_ops, limit
        raise _Stop

    monkeypatch.setattr(ident, "require_memory", memory)
    monkeypatch.setattr(ident, "require_work", work)
    with pytest.raises(_Stop):
        est.fit(recs, **({} if est.creep is None else {}))
    assert seen["limit"] == 3e11
    return seen["bytes"], seen["ops"]


def test_cost_estimate_of_a_classical_fit_by_hand(monkeypatch: pytest.MonkeyPatch) -> None:
    recs = _records()  # 1000 + 1001 samples, max_rows 500 -> stride ceil(2001 / 500) = 5
    n_bytes, ops = _costs(monkeypatch, PIIdentifier("pi", n_operators=10, max_rows=500), recs)
    assert n_bytes == 8.0 * 1001 * 10 * 2  # operator outputs of the longest record, twice
    p, rows, n_fits = 10 + 2, 2001 / 5, 3 * 2 + 2  # operators + one offset per record
    assert ops == pytest.approx(n_fits * (rows * p * p / 2 + p**3), rel=1e-12)


def test_cost_estimate_of_a_modified_fit_with_creep_by_hand(monkeypatch: pytest.MonkeyPatch) -> None:
    recs = _records(1000, 1000)  # 2000 samples, default max_rows: stride 1
    est = PIIdentifier("modified-pi", n_operators=6, max_evaluations=7, creep=[0.01, 0.1, 1.0], sample_time=1e-3)
    n_bytes, ops = _costs(monkeypatch, est, recs)
    assert n_bytes == 8.0 * 1000 * (6 + 3) * 2
    p, rows, n_fits = 6 + 3 + 2, 2000, 3 * 2 + 2 + 7  # the search does one weight fit per evaluation
    assert ops == pytest.approx(n_fits * (rows * p * p / 2 + p**3), rel=1e-12)
    # the default budget: 1000 evaluations with the input warp, 500 without
    _, ops_warp = _costs(monkeypatch, PIIdentifier("modified-pi", n_operators=6), recs)
    _, ops_plain = _costs(monkeypatch, PIIdentifier("modified-pi", n_operators=6, input_warp=False), recs)
    one = rows * 8 * 8 / 2 + 8**3
    assert (ops_warp, ops_plain) == (pytest.approx((8 + 1000) * one), pytest.approx((8 + 500) * one))


def test_the_operations_limit_is_inclusive(monkeypatch: pytest.MonkeyPatch) -> None:
    recs = _records()
    p, rows = 4 + 2, 2001  # default max_rows: every sample is a row
    ops = (3 * 2 + 2) * (rows * p * p / 2 + p**3)
    monkeypatch.setattr(ident, "MAX_FIT_OPERATIONS", ops)
    PIIdentifier("pi", n_operators=4).fit(recs)  # exactly at the limit: allowed
    monkeypatch.setattr(ident, "MAX_FIT_OPERATIONS", ops * (1 - 1e-9))
    with pytest.raises(ResourceError, match="a pi fit with 4 operators would take about"):
        PIIdentifier("pi", n_operators=4).fit(recs)


def test_operator_caps_per_model_kind() -> None:
    for kind, cap in (("pi", 1000), ("modified-pi", 100)):
        PIIdentifier(kind, n_operators=cap).validate_params()
        with pytest.raises(ParameterError, match=f"at most {cap} for a {kind} model"):
            PIIdentifier(kind, n_operators=cap + 1).validate_params()


def test_summary_reports_the_median_threshold_ratios() -> None:
    r = np.arange(5) * 10.0
    rc = np.array([0.0, 3.0, 5.0, 9.0, 40.0])  # rc/r over r > 0: 0.3, 0.25, 0.3, 1.0 -> median 0.3
    ra = 2.0 * r
    rb = np.array([0.0, 10.0, 20.0, 30.0, 40.0])  # rb/ra: 0.5 each
    model = ModifiedPIModel(r=r, rc=rc, ra=ra, rb=rb, weights=[1.0, 0.1, 0.1, 0.1, 0.1], input_offset=2.5)
    fit = HysteresisFit(model, (1.0,), (0.5,), (0.0,), ("zero",), 3, True, "done")
    text = fit.summary()
    assert "rc/r = 0.3000, ra/r = 2.0000, rb/ra = 0.5000, centre = 2.5" in text
    flat = ModifiedPIModel(r=np.zeros(2), rc=np.zeros(2), ra=np.zeros(2), rb=np.zeros(2), weights=[1.0, 0.1])
    flat_text = HysteresisFit(flat, (1.0,), (0.5,), (0.0,), ("zero",), 3, True, "done").summary()
    assert "rc/r = nan" in flat_text  # no threshold above 0: no ratio, not a division by zero


def test_hysteresis_fit_is_frozen() -> None:
    fit = PIIdentifier("pi", n_operators=4).fit(_records()[0])
    with pytest.raises(AttributeError):
        fit.success = False  # type: ignore[misc]


def test_auto_start_is_zero_only_within_one_percent_of_the_range_at_rest() -> None:
    true = PIModel(r=np.arange(4) * 25.0, weights=[0.01, 0.004, 0.003, 0.002])
    ramp = np.r_[np.linspace(0, 100, 200), np.linspace(100, -100, 400), np.linspace(-100, 100, 400)]
    for u0, expected in ((1.99, "zero"), (-1.99, "zero"), (2.01, "ascending")):
        u = ramp + u0 * (1 - np.arange(ramp.size) / ramp.size)  # first sample u0, range ~200
        start = true.with_state(true.consistent_state(u[0], "ascending"))
        fit = PIIdentifier("pi", n_operators=4).fit([(u, start.simulate(u)[:, 0])])
        assert fit.initial_states == (expected,), u0


def test_a_given_initial_state_is_kept_not_chosen() -> None:
    # a record generated from a "descending" start, fitted with initial_state="ascending": the
    # fit must use the start it is given ("auto" would pick "descending")
    true = PIModel(r=np.arange(4) * 25.0, weights=[0.01, 0.004, 0.003, 0.002])
    u = np.r_[np.linspace(60, -100, 300), np.linspace(-100, 100, 400)]
    y = true.with_state(true.consistent_state(u[0], "descending")).simulate(u)[:, 0]
    assert PIIdentifier("pi", n_operators=4).fit((u, y)).initial_states == ("descending",)
    assert PIIdentifier("pi", n_operators=4, initial_state="ascending").fit((u, y)).initial_states == ("ascending",)


def test_closed_form_inverse_needs_a_linear_term_first() -> None:
    from stageid import ModelError
    from stageid.hysteresis import pi_inverse

    with pytest.raises(ModelError, match=r"needs r\[0\] = 0 \(a linear term\); got r\[0\] = 5"):
        pi_inverse(PIModel(r=[5.0, 25.0], weights=[0.01, 0.004]))
