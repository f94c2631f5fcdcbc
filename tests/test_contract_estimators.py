"""One contract for every estimator: configure, fit, get an immutable result (STYLE.md).

The estimators are found by :func:`stageid.base.estimators` (every concrete subclass of
:class:`stageid.base.Estimator` in the package), never listed by hand: a new estimator that
has no data case below fails ``test_every_estimator_has_a_case``.

- ``__init__`` stores its keyword hyper-parameters unchanged and does no work;
- every ``__init__`` parameter is declared in ``parameter_constraints`` and a value no
  constraint accepts makes ``fit`` raise :class:`ParameterError` naming that parameter;
- ``get_params`` returns the parameters, ``repr`` shows those that differ from the defaults;
- ``fit`` never modifies the caller's data and returns a frozen result that keeps no
  training array;
- a second ``fit`` on other data gives an independent result (the first is unchanged).
"""

import dataclasses
import inspect
import json

import numpy as np
import pytest

from stageid import ParameterError
from stageid.base import Estimator, estimators
from stageid.data import Experiment
from stageid.models import StateSpaceModel, feedback


def _siso_data(seed):
    rng = np.random.default_rng(seed)
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=0.01)
    u = rng.standard_normal((3000, 1))
    return Experiment(u, g.simulate(u) + 1e-3 * rng.standard_normal((3000, 1)), 0.01, ("u",), ("y",))


def _hysteresis_data(seed):
    from stageid.plants.piezo_actuator import EXPERIMENTS

    # the reference actuator is noise-free, so a different seed alone would give the same record
    return EXPERIMENTS["decaying-triangle" if seed == 0 else "decaying-sine"](seed=seed)


_CONTROLLER = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], dt=0.001)


def _closed_loop_data(seed):
    # an unstable first-order plant under a proportional controller; the reference is the input
    rng = np.random.default_rng(seed)
    G = StateSpaceModel([[1.02]], [[0.05]], [[1.0]], [[0.0]], dt=0.001)  # unstable
    cl = feedback(G, _CONTROLLER)
    r = rng.standard_normal((4000, 1))
    r[:100] = 0.0  # the loop starts at rest, as real records do
    yu = cl.simulate(r)
    return Experiment(r, yu[:, :1] + 1e-5 * rng.standard_normal((4000, 1)), 0.001, ("r_y",), ("y",))


def _unknown_controller_data(seed):
    # an unstable 2x2 stage under a filtered PD the fits are not told; references recorded
    from stageid.plants import levitated_pair

    r, u, y = levitated_pair.record(3000, seed=seed)
    return Experiment(np.hstack([r, u]), y, levitated_pair.DT, ("r1", "r2", "u1", "u2"), ("x1", "x2"))


def _periodic_data(seed):
    # 15 periods of a random-phase signal of 200 samples through a stable plant (periodic averaging)
    rng = np.random.default_rng(seed)
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.5, 0.1]], [[0.0]], dt=0.01)
    u = np.tile(rng.standard_normal((200, 1)), (15, 1))
    return Experiment(u, g.simulate(u) + 1e-3 * rng.standard_normal((3000, 1)), 0.01, ("u",), ("y",))


def _result_model(result):
    model = getattr(result, "model", None)
    return model if model is not None else result.plant


def _model_text(model):
    """The model as JSON: ``to_dict`` for parametric models, the table columns for a frequency response."""
    if hasattr(model, "to_dict"):
        return json.dumps(model.to_dict())
    return json.dumps({k: np.asarray(v).tolist() for k, v in model.to_columns().items()})


# estimator class name -> (a configured instance, data of seed k)
CASES = {
    "HankelMAP": (lambda cls: cls(horizon=8, order=2), _siso_data),
    "PIIdentifier": (lambda cls: cls("pi", n_operators=8), _hysteresis_data),
    "StageIdentifier": (lambda cls: cls("pi", n_operators=8, dynamics=1, creep=None), _hysteresis_data),
    "ClosedLoopIdentification": (
        lambda cls: cls(_CONTROLLER, orders=1, structure="full", band=(1.0, 100.0)),
        _closed_loop_data,
    ),
    "FRDIdentification": (lambda cls: cls(order=2, sample_time=0.01), _siso_data),
    "PreisachIdentifier": (lambda cls: cls(n_levels=8), _hysteresis_data),
    "DirectPredictionError": (lambda cls: cls(order=4, horizon=10, references=["r1", "r2"]), _unknown_controller_data),
    "TwoStageProjection": (
        lambda cls: cls(order=4, horizon=10, sensitivity_order=6, references=["r1", "r2"]),
        _unknown_controller_data,
    ),
    "JointInputOutput": (lambda cls: cls(order=6, horizon=10, references=["r1", "r2"]), _unknown_controller_data),
    "WelchFRF": (lambda cls: cls(segment=256), _siso_data),
    "LocalPolynomialFRF": (lambda cls: cls(degree=2), _siso_data),
    "PeriodicFRF": (lambda cls: cls(periods=15, transient_periods=1), _periodic_data),
}

ESTIMATORS = {cls.__name__: cls for cls in estimators().values() if not cls.__module__.startswith("tests")}


def test_the_registry_finds_the_estimators():
    # the three estimators of the papers and the nonparametric FRF estimators at least; the
    # registry is filled by subclassing alone
    assert {"HankelMAP", "PIIdentifier", "ClosedLoopIdentification"} <= set(ESTIMATORS)
    assert {"WelchFRF", "LocalPolynomialFRF", "PeriodicFRF"} <= set(ESTIMATORS)
    for cls in ESTIMATORS.values():
        assert issubclass(cls, Estimator)


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_every_estimator_has_a_case(name):
    assert name in CASES, f"{name} is an Estimator without a data case in {__name__}.CASES; add one"


def test_a_new_subclass_is_registered():
    class Probe(Estimator):
        def __init__(self, k=1):
            self.k = k

        def fit(self, data):
            self.validate_params()

    assert any(cls is Probe for cls in estimators().values())


def test_a_former_keyword_still_works_with_a_warning():
    class Renamed(Estimator):
        abstract = True
        renamed_parameters = {"dt": "sample_time", "fmin": ("band", 0), "fmax": ("band", 1)}

        def __init__(self, sample_time=None, band=None):
            self.sample_time, self.band = sample_time, band

    with pytest.warns(DeprecationWarning, match="`dt` of Renamed is now `sample_time`"):
        est = Renamed(dt=0.1, fmin=1.0, fmax=5.0)
    assert est.get_params() == {"sample_time": 0.1, "band": (1.0, 5.0)}
    with pytest.raises(ParameterError, match="former name of `sample_time`"):
        Renamed(dt=0.1, sample_time=0.2)

    class Subclassed(Renamed):  # its own __init__ inherits the former names
        def __init__(self, sample_time=None, band=None, extra=1):
            super().__init__(sample_time, band)
            self.extra = extra

    with pytest.warns(DeprecationWarning, match="`dt` of Subclassed is now `sample_time`"):
        assert Subclassed(dt=0.3).sample_time == 0.3


@pytest.mark.parametrize("name", sorted(estimators()))
def test_former_keywords_name_declared_parameters(name):
    cls = estimators()[name]
    for old, new in cls.renamed_parameters.items():
        target = new if isinstance(new, str) else new[0]
        assert target in cls.parameter_names(), f"{name}: `{old}` maps to undeclared `{target}`"
        assert old not in cls.parameter_names(), f"{name}: `{old}` is both former and current"


def _package_classes():
    import importlib
    import pkgutil

    import stageid

    for info in pkgutil.walk_packages(stageid.__path__, "stageid."):
        if info.name.endswith("__main__"):  # importing it runs the command line
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if inspect.isclass(obj) and obj.__module__ == module.__name__:
                yield f"{module.__name__}.{name}", obj


def test_every_class_with_fit_is_an_estimator():
    # a class the user can call .fit on follows the one contract; a step inside an
    # estimator names its method otherwise (solve, refine, ...)
    outside = [
        name
        for name, cls in _package_classes()
        if callable(getattr(cls, "fit", None)) and not issubclass(cls, Estimator)
    ]
    assert not outside, f"classes with fit() outside the Estimator base: {outside}"


def _make(name):
    make, data = CASES[name]
    return make(ESTIMATORS[name]), data


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_init_stores_parameters_unchanged_and_declares_them(name):
    cls = ESTIMATORS[name]
    sentinels = {}
    for p in cls.parameter_names():
        # an object no real setting equals: __init__ must keep it as it came (identity)
        sentinels[p] = object()
    est = cls(**sentinels)
    for p, value in sentinels.items():
        assert getattr(est, p) is value, f"{name}.__init__ must store `{p}` unchanged"
    assert set(cls.parameter_constraints) == set(cls.parameter_names()), "declare every parameter once"


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_get_params_and_repr(name):
    est, _ = _make(name)
    params = est.get_params()
    assert list(params) == list(type(est).parameter_names())
    text = repr(est)
    sig = inspect.signature(type(est).__init__)
    for p, v in params.items():
        default = sig.parameters[p].default
        changed = default is inspect.Parameter.empty or not (type(v) is type(default) and v == default)
        assert (f"{p}=" in text) == changed, f"repr shows exactly the non-default parameters: {text}"


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_every_bad_setting_is_one_parameter_error(name):
    est, data = _make(name)
    exp = data(0)
    for p in type(est).parameter_names():
        bad = est.get_params()
        bad[p] = object()  # no declared constraint accepts a bare object
        broken = type(est)(**bad)
        with pytest.raises(ParameterError) as info:
            broken.fit(exp)
        message = str(info.value)
        assert message.startswith(f"`{p}` of {name} must be ") and "\n" not in message, message


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_fit_keeps_caller_data_and_returns_frozen_result(name):
    est, data = _make(name)
    exp = data(0)
    u_before, y_before = exp.u.copy(), exp.y.copy()
    result = est.fit(exp)
    np.testing.assert_array_equal(exp.u, u_before)
    np.testing.assert_array_equal(exp.y, y_before)
    assert dataclasses.is_dataclass(result)
    field = dataclasses.fields(result)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(result, field, None)
    # no array of the record's length is kept anywhere in the result (fields and nested values)
    n = exp.u.shape[0]
    stack, seen = [result], set()
    while stack:
        obj = stack.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        if isinstance(obj, np.ndarray):
            assert n not in obj.shape, f"{name}'s result keeps an array of shape {obj.shape}"
        elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            stack.extend(getattr(obj, f.name) for f in dataclasses.fields(obj))
        elif isinstance(obj, dict):
            stack.extend(obj.values())
        elif isinstance(obj, (list, tuple)):
            stack.extend(obj)
    before = _model_text(_result_model(result))
    second = est.fit(data(1))
    assert _model_text(_result_model(result)) == before  # the first result is untouched
    assert _model_text(_result_model(second)) != before  # and the second fit used the new data


@pytest.mark.parametrize("name", sorted(ESTIMATORS))
def test_every_result_has_the_same_face(name):
    """One ``fit(data)``; a ``*Result`` with ``.model``, ``summary()`` and read-only ``diagnostics``
    that survives pickling (a worker returns it, a study caches it)."""
    import collections.abc
    import pickle

    est, data = _make(name)
    fit = inspect.signature(type(est).fit).parameters
    required = [n for n, p in fit.items() if n != "self" and p.default is inspect.Parameter.empty]
    assert required == ["data"], f"{name}.fit requires {required}"
    result = est.fit(data(0))
    assert type(result).__name__.endswith("Result")
    assert result.model is not None
    assert isinstance(result.summary(), str) and result.summary()
    assert isinstance(result.diagnostics, collections.abc.Mapping)
    with pytest.raises(TypeError):
        result.diagnostics["probe"] = 1
    again = pickle.loads(pickle.dumps(result))
    assert _model_text(_result_model(again)) == _model_text(_result_model(result))


def test_closed_loop_recovers_the_unstable_pole():
    est, data = _make("ClosedLoopIdentification")
    result = est.fit(data(0))
    # the unstable pole at z = 1.02 (s = ln(1.02)/dt) is recovered from closed-loop data
    s_true = np.log(1.02) / 0.001
    assert np.min(np.abs(np.asarray(result.unstable_poles) - s_true)) < 0.05 * s_true
