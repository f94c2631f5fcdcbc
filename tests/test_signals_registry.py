"""Registry, shared contract of every generator (limits, seeds, shapes), docstring examples."""

from __future__ import annotations

import doctest
import importlib
import inspect
import re

import numpy as np
import pytest

from stageid import SignalError
from stageid.signals import SIGNAL_KINDS, check_limits, crest_factor, generate, signal_parameters, time_vector

# Small valid parameter sets for every kind (kept short: the contract, not the physics)
EXAMPLES: dict[str, dict] = {
    "chirp": dict(f0=1.0, f1=50.0, duration=1.0, dt=1e-3, amplitude=2.0, offset=3.0),
    "log-chirp": dict(f0=1.0, f1=50.0, duration=1.0, dt=1e-3, amplitude=2.0, offset=3.0),
    "prbs": dict(n_samples=500, amplitude=2.0, offset=3.0, seed=1),
    "random": dict(n_samples=500, dt=1e-3, f_low=1.0, f_high=100.0, amplitude=2.0, offset=3.0, seed=1),
    "multisine": dict(n_samples=500, dt=1e-3, f_low=1.0, f_high=100.0, amplitude=2.0, offset=3.0, seed=1),
    "sine": dict(freq=5.0, duration=1.0, dt=1e-3, amplitude=2.0, offset=3.0),
    "triangle": dict(freq=5.0, duration=1.0, dt=1e-3, amplitude=2.0, offset=3.0),
    "decaying-sine": dict(freq=5.0, n_cycles=4, dt=1e-3, amplitude=2.0, offset=3.0),
    "decaying-triangle": dict(freq=5.0, n_cycles=4, dt=1e-3, amplitude=2.0, offset=3.0),
    "forc": dict(minimum=1.0, maximum=5.0, n_reversals=4, freq=5.0, dt=1e-3),
}


def test_kinds_are_the_documented_closed_set():
    assert list(SIGNAL_KINDS) == list(EXAMPLES)
    for kind, func in SIGNAL_KINDS.items():
        assert callable(func) and re.fullmatch(r"[a-z]+(-[a-z]+)*", kind)


@pytest.mark.parametrize("kind", list(EXAMPLES))
def test_every_kind_contract(kind):
    params = EXAMPLES[kind]
    x = generate(kind, **params)
    # 1-D float, within offset +- amplitude (here 1..5), equal to the direct call
    assert x.ndim == 1 and x.dtype == np.float64 and x.size >= 2
    assert np.all(np.isfinite(x))
    assert x.min() >= 1.0 - 1e-12 and x.max() <= 5.0 + 1e-12
    assert np.array_equal(x, SIGNAL_KINDS[kind](**params))
    # deterministic: the same parameters (and seed) give the same signal
    assert np.array_equal(x, generate(kind, **params))
    # limits: accepted when inside, one-line error naming both ranges when outside
    generate(kind, **params, limits=(1.0, 5.0))
    with pytest.raises(SignalError, match=r"^[a-z -]+ spans \[[-\d.e]+, [-\d.e]+\] but limits are \[2, 4\]\.$"):
        generate(kind, **params, limits=(2.0, 4.0))
    with pytest.raises(SignalError, match=r"`limits` of .* must be"):
        generate(kind, **params, limits=(4.0, 2.0))
    # every generator documents itself: numpydoc sections and a runnable example
    doc = inspect.getdoc(SIGNAL_KINDS[kind])
    for section in ("Parameters", "Returns", "Raises", "Examples"):
        assert f"\n{section}\n" in doc
    assert all(p.annotation is not inspect.Parameter.empty for p in signal_parameters(kind).values())


def test_generate_unknown_kind_lists_choices():
    with pytest.raises(SignalError) as err:
        generate("square", freq=1.0)
    msg = str(err.value)
    assert "got 'square'" in msg
    for kind in SIGNAL_KINDS:
        assert kind in msg


def test_generate_unknown_and_missing_parameters():
    with pytest.raises(SignalError, match=re.escape("got unknown frequency")):
        generate("sine", frequency=1.0, duration=1.0, dt=1e-3)
    with pytest.raises(SignalError, match=re.escape("requires parameters freq, duration, dt; got no dt.")):
        generate("sine", freq=1.0, duration=1.0)


def test_generate_passes_a_generators_own_kind_parameter():
    params = dict(n_samples=1000, dt=1e-3, f_low=1.0, f_high=100.0)
    x = generate("multisine", **params, kind="schroeder")
    assert np.array_equal(x, SIGNAL_KINDS["multisine"](**params, kind="schroeder"))
    assert not np.allclose(x, generate("multisine", **params, kind="random-phase", seed=0))


def test_signal_parameters_lists_required_first():
    params = signal_parameters("chirp")
    assert params["f0"].annotation is float and params["method"].default == "linear"
    assert params["limits"].annotation == (tuple[float, float] | None)
    required = [n for n, p in params.items() if p.default is inspect.Parameter.empty]
    assert required == ["f0", "f1", "duration", "dt"]
    with pytest.raises(SignalError, match="signal kind must be one of"):
        signal_parameters("nope")


def test_helpers():
    np.testing.assert_array_equal(time_vector(3, 0.1), [0.0, 0.1, 0.2])
    with pytest.raises(SignalError, match=re.escape("`dt` of time_vector must be a number > 0; got -1")):
        time_vector(3, -1.0)
    with pytest.raises(SignalError, match=re.escape("`n_samples` of time_vector must be an integer >= 2; got 1")):
        time_vector(1, 0.1)
    assert crest_factor(np.array([1.0, -1.0, 1.0, -1.0])) == pytest.approx(1.0)
    with pytest.raises(SignalError, match="constant"):
        crest_factor(np.ones(5))
    with pytest.raises(SignalError, match=re.escape("chirp spans [-1, 41] um but limits are [0, 40] um.")):
        check_limits(np.array([-1.0, 41.0]), (0, 40), "chirp", "um")
    # a few ulps over the limit (sin rounding) are not an error
    check_limits(np.array([40.0 * (1 + 1e-15)]), (0.0, 40.0), "sine")
    with pytest.raises(SignalError, match=r"must be a pair"):
        check_limits(np.zeros(3), (1.0,), "sine")


def test_caller_limits_tuple_and_arrays_not_modified():
    lim = [0.0, 40.0]
    generate("sine", freq=1.0, duration=1.0, dt=1e-2, amplitude=10.0, offset=20.0, limits=lim)
    assert lim == [0.0, 40.0]


@pytest.mark.parametrize("module", ["_common", "sweeps", "random", "periodic", "hysteresis", "registry"])
def test_docstring_examples_run(module):
    mod = importlib.import_module(f"stageid.signals.{module}")
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0
    assert result.failed == 0
