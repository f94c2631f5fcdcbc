"""The hysteresis estimators' one ``fit(data)`` shape: the data as one argument, channel names as
parameters, the records read once and handed down, one name per idea on the results."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from stageid import DataError
from stageid.data import Experiment
from stageid.hysteresis import (
    HysteresisFit,
    HysteresisResult,
    PIIdentifier,
    PIModel,
    PreisachFit,
    PreisachIdentifier,
    PreisachResult,
    StageFit,
    StageIdentifier,
    StageResult,
)
from stageid.hysteresis.identify import pi as pi_module
from stageid.hysteresis.identify import preisach as preisach_module
from stageid.hysteresis.identify import records as records_module
from stageid.hysteresis.stage import identification as stage_module
from stageid.signals import decaying_triangle

DT = 1e-3
TRUE = PIModel(r=[0.0, 2.5, 5.0, 7.5], weights=[1.0, 0.4, 0.2, 0.1])


def _record(name="a"):
    u = decaying_triangle(1.0, 8, DT, amplitude=10.0)
    return Experiment(u, TRUE.simulate(u), DT, ("drive",), ("pos",), name=name)


def _two_channel_record():
    # the drive beside an unrelated channel, the position beside a scaled copy of it
    u = decaying_triangle(1.0, 8, DT, amplitude=10.0)
    y = TRUE.simulate(u)[:, 0]
    other = np.cos(np.arange(u.size) * 0.01)
    return Experiment(np.c_[other, u], np.c_[y, 3.0 * y], DT, ("aux", "drive"), ("pos", "pos3"))


def _counting_reads(monkeypatch):
    """Count every read of the records, whichever module calls it."""
    calls = []
    original = records_module.read_records

    def counted(*args, **kwargs):
        calls.append(args[0])
        return original(*args, **kwargs)

    for module in (pi_module, preisach_module, stage_module):
        monkeypatch.setattr(module, "read_records", counted)
    return calls


@pytest.mark.parametrize("kind", ["pi", "preisach"])
def test_a_stage_fit_reads_its_records_once(monkeypatch, kind):
    calls = _counting_reads(monkeypatch)
    est = StageIdentifier(kind, n_operators=4, n_levels=6, dynamics=None, creep=None)
    fit = est.fit([_record("a"), _record("b")])
    assert len(calls) == 1  # the hysteresis identification of step 1 takes the records as read
    assert fit.model.hysteresis.inputs == ("drive",) and fit.model.hysteresis.outputs == ("pos",)


def test_channel_names_are_parameters_and_the_former_call_warns():
    rec = _record()
    new = PIIdentifier("pi", n_operators=4, inputs="V", outputs="x").fit(rec)
    with pytest.warns(DeprecationWarning, match=r"PIIdentifier\(inputs=..., outputs=...\)\.fit\(data\)"):
        old = PIIdentifier("pi", n_operators=4).fit(rec, "V", "x")
    assert new.model.inputs == old.model.inputs == ("V",)
    assert new.model.outputs == old.model.outputs == ("x",)
    np.testing.assert_array_equal(new.model.weights, old.model.weights)
    # the former call fitted a copy: the estimator's own settings are untouched
    est = PreisachIdentifier(n_levels=6)
    with pytest.warns(DeprecationWarning):
        res = est.fit(rec, outputs="z")
    assert est.outputs is None and res.model.outputs == ("z",) and res.estimator.outputs == "z"


def test_the_former_stage_call_warns_and_keeps_progress():
    seen = []
    est = StageIdentifier("pi", n_operators=4, dynamics=None, creep=None)
    with pytest.warns(DeprecationWarning, match="StageIdentifier"):
        fit = est.fit(_record(), "V", progress=lambda *a: seen.append(a))
    assert fit.model.hysteresis.inputs == ("V",) and seen


def test_the_channel_of_a_record_with_several_is_chosen_by_name():
    rec = _two_channel_record()
    fit = PIIdentifier("pi", n_operators=4, inputs="drive", outputs="pos").fit(rec)
    assert fit.model.inputs == ("drive",) and fit.max_error_percent[0] < 1e-6
    scaled = PIIdentifier("pi", n_operators=4, inputs="drive", outputs="pos3").fit(rec)
    np.testing.assert_allclose(scaled.model.weights, 3.0 * fit.model.weights, rtol=1e-6)
    with pytest.raises(DataError, match=r"record 0 has 2 \(aux, drive\): give `inputs`"):
        PIIdentifier("pi", n_operators=4).fit(rec)
    with pytest.raises(DataError, match=r"`outputs`='x' is not one of them"):
        PIIdentifier("pi", n_operators=4, inputs="drive", outputs="x").fit(rec)


def test_creep_is_the_name_of_the_creep_time_constants():
    rec = _record()
    with pytest.warns(DeprecationWarning, match="`creep_time_constants` of PIIdentifier is now `creep`"):
        old = PIIdentifier("pi", n_operators=4, creep_time_constants=(0.1,))
    assert old.creep == (0.1,) and "creep_time_constants" not in old.get_params()
    new = PIIdentifier("pi", n_operators=4, creep=(0.1,)).fit(rec)
    np.testing.assert_array_equal(old.fit(rec).model.creep.weights, new.model.creep.weights)


def test_results_have_one_name_diagnostics_and_the_settings_of_their_fit():
    assert HysteresisFit is HysteresisResult and PreisachFit is PreisachResult and StageFit is StageResult
    rec = _record()
    est = PIIdentifier("modified-pi", n_operators=4, input_warp=False, max_evaluations=20)
    results = [
        est.fit(rec),
        PreisachIdentifier(n_levels=6).fit(rec),
        StageIdentifier("pi", n_operators=4, dynamics=None, creep=None).fit(rec),
    ]
    for res, key in zip(results, ("n_evaluations", "filled_cells", "dynamics_order")):
        assert key in res.diagnostics and res.diagnostics["records"] == 1
        assert res.diagnostics["max_error_percent"] == max(res.max_error_percent)
        with pytest.raises(TypeError):
            res.diagnostics["records"] = 2  # read-only
        assert res.summary() and res.model is not None
    assert results[0].diagnostics["message"] == results[0].message
    est.n_operators = 5  # a later change of the estimator is not the result's
    assert results[0].estimator.n_operators == 4 and results[0].estimator is not est


def test_a_stage_fit_with_both_passes_uses_no_former_call_form():
    # dynamics found: step 4 fits the thresholds again on derived records, in the new shape too
    rec = _record()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        StageIdentifier("pi", n_operators=4, dynamics=1, creep=None).fit(rec)
