"""Residual tests of a model on records (MATLAB ``resid``): fit, NRMSE, whiteness, independence.

:func:`validate_model` simulates a model on every record and runs the two correlation tests of
:mod:`.correlation_tests` (re-exported here) on each output's residual; :func:`validation_json`
is its JSON form (what ``stageid validate`` writes).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from .correlation_tests import (  # the tests themselves, re-exported where they were
    ALPHA,
    MAX_LAG,
    CorrelationTest,
    check_test_settings,
    independence_test,
    min_samples,
    whiteness_test,
)

__all__ = [
    "MAX_LAG",
    "ALPHA",
    "CorrelationTest",
    "residual_tests",
    "whiteness_test",
    "independence_test",
    "min_samples",
    "validate_model",
    "validation_json",
]


def residual_tests(
    residuals: Sequence[np.ndarray],
    inputs: Sequence[np.ndarray],
    input_names: Sequence[str],
    max_lag: int = MAX_LAG,
    alpha: float = ALPHA,
) -> dict:
    """Both tests for one output: ``{"whiteness": CorrelationTest, "independence": {name: CorrelationTest}}``.

    ``residuals`` is one 1-D residual per record, ``inputs`` one ``(n_samples, n_inputs)``
    array per record, columns named by ``input_names``.
    """
    white = whiteness_test(residuals, max_lag, alpha)
    indep = {
        name: independence_test(residuals, [np.asarray(u)[:, j] for u in inputs], max_lag, alpha)
        for j, name in enumerate(input_names)
    }
    return {"whiteness": white, "independence": indep}


def validate_model(model, experiments, max_lag: int = MAX_LAG, alpha: float = ALPHA, simulated=None) -> dict:
    """Simulate ``model`` on every record; fit %, NRMSE and both residual tests per output.

    Parameters
    ----------
    model : StateSpaceModel, TransferMatrix or a hysteresis model
        Anything with ``simulate(u, dt=...)``, ``inputs`` and ``outputs``.
    experiments : sequence of Experiment
        Channels named and ordered as the model's.
    max_lag, alpha : as :func:`whiteness_test`.
    simulated : list of ndarray, optional
        The model's outputs per record when the caller simulated them (e.g. with an initial
        condition estimated on the record); default ``model.simulate`` from the model's state.

    Returns
    -------
    dict
        ``{"outputs": {name: {"fit_percent", "nrmse", "whiteness": CorrelationTest,
        "independence": {input: CorrelationTest}, "untested_inputs": [input]}}, "residuals": [ndarray
        (n_samples, n_outputs) per record], "simulated": [ndarray per record]}``; fit % and NRMSE
        over the pooled records.  An input constant in every record has no independence test; it
        is listed in ``untested_inputs``.

    Raises
    ------
    DataError
        Channels that differ from the model's, too few samples for ``max_lag``, every input
        constant, or a residual that is constant (named with the records).
    """
    from .metrics import fit_percent, nrmse

    exps = list(experiments)
    for exp in exps:
        if tuple(exp.input_names) != tuple(model.inputs) or tuple(exp.output_names) != tuple(model.outputs):
            raise DataError(
                f"record {exp.name or '?'} has inputs {','.join(exp.input_names)} and outputs "
                f"{','.join(exp.output_names)}; the model expects {','.join(model.inputs)} and {','.join(model.outputs)}."
            )
    n = sum(exp.n_samples for exp in exps)
    check_test_settings(n, max_lag, alpha)
    if simulated is None:
        simulated = [model.simulate(exp.u, dt=exp.dt) for exp in exps]
    simulated = [np.asarray(ys, dtype=float).reshape(exp.y.shape) for exp, ys in zip(exps, simulated)]
    residuals = [exp.y - ys for exp, ys in zip(exps, simulated)]
    y_all, ys_all = np.vstack([exp.y for exp in exps]), np.vstack(simulated)
    fits, errs = fit_percent(y_all, ys_all), nrmse(y_all, ys_all)
    moving = _moving_inputs(model.inputs, exps)
    outputs = {}
    for i, name in enumerate(model.outputs):
        if all(np.ptp(e[:, i]) == 0 for e in residuals):
            raise DataError(
                f"the residual of output '{name}' is constant in {_record_names(exps)} (the model reproduces "
                "it exactly); the residual tests need a residual that varies."
            )
        u = [exp.u[:, moving] for exp in exps]
        tests = residual_tests([e[:, i] for e in residuals], u, [model.inputs[j] for j in moving], max_lag, alpha)
        untested = [n for j, n in enumerate(model.inputs) if j not in moving]
        outputs[name] = {"fit_percent": float(fits[i]), "nrmse": float(errs[i]), **tests, "untested_inputs": untested}
    return {"outputs": outputs, "residuals": residuals, "simulated": simulated}


def _record_names(exps) -> str:
    names = [f"'{e.name}'" if e.name else "the record" for e in exps]
    return "record " + names[0] if len(names) == 1 else "records " + ", ".join(names)


def _moving_inputs(names: Sequence[str], exps) -> list[int]:
    """Columns of the inputs that vary in some record: an input held constant everywhere (an axis
    not excited) has no independence test, and is listed as untested instead of failing the rest."""
    moving = [j for j in range(len(names)) if any(np.ptp(exp.u[:, j]) > 0 for exp in exps)]
    if not moving:
        raise DataError(
            f"every input ({', '.join(names)}) is constant in {_record_names(exps)}; "
            "the residual tests need an input that varies."
        )
    return moving


def validation_json(result: dict) -> dict:
    """The JSON-ready form of :func:`validate_model`'s outputs (tests as dicts, arrays dropped).

    ``independence`` holds ``pass``/``max_abs``/``bound``/``lags`` over all inputs (passes when
    every input passes; ``max_abs`` the largest over inputs) and ``inputs``: one test per input.
    """
    out = {}
    for name, entry in result["outputs"].items():
        indep = {k: t.to_dict() for k, t in entry["independence"].items()}
        first = next(iter(entry["independence"].values()))
        out[name] = {
            **{k: v for k, v in entry.items() if k not in ("whiteness", "independence")},
            "whiteness": entry["whiteness"].to_dict(),
            "independence": {
                "pass": all(t["pass"] for t in indep.values()),
                "max_abs": max(t["max_abs"] for t in indep.values()),
                "bound": first.bound,
                "lags": [int(k) for k in first.lags],
                "inputs": indep,
            },
        }
    return {"outputs": out}
