"""The one rule per kind of setting (stageid.checks) and the estimator base (stageid.base)."""

import numpy as np
import pytest

from stageid import ParameterError, SignalError
from stageid.base import Band, Boolean, Estimator, InstanceOf, Interval, Options, Satisfies
from stageid.checks import check_band, check_choice, check_integer, check_real, check_seed


@pytest.mark.parametrize(
    "bad", ["0.002", True, np.bool_(False), float("nan"), float("inf"), 10**5000, None, [1.0]], ids=range(8)
)
def test_a_number_is_a_finite_real_never_a_string_or_bool(bad):
    with pytest.raises(ParameterError, match=r"^`dt` of f must be a number > 0; got "):
        check_real(bad, "dt", "f", low=0.0, closed="neither")


def test_number_bounds_and_message_shape():
    assert check_real(np.float32(0.5), "x", "f", low=0.0, high=1.0) == 0.5
    with pytest.raises(ParameterError, match=r"^`x` of f must be a number in \(0, 1\]; got 0\.0\.$"):
        check_real(0.0, "x", "f", low=0.0, high=1.0, closed="right")
    assert check_integer(np.int64(3), "n", "f", low=1) == 3
    with pytest.raises(SignalError, match=r"^`n` of f must be an integer >= 1; got True\.$"):
        check_integer(True, "n", "f", low=1, error=SignalError)
    with pytest.raises(ParameterError, match=r"got an integer of about 5001 digits\.$"):  # no repr exists
        check_integer(-(10**5000), "n", "f", low=1)
    with pytest.raises(ParameterError, match=r"\(list of 30000 characters\)\.$"):  # cut short
        check_integer([1111] * 5000, "n", "f", low=1)
    with pytest.raises(ParameterError, match=r"one of 'a', 'b'"):
        check_choice("c", "m", "f", ("a", "b"))


def test_one_rule_for_bands():
    assert check_band((0, 10)) == (0.0, 10.0)  # 0 Hz may start a band
    assert check_band(np.array([1.0, 250.0]), nyquist=250.0) == (1.0, 250.0)
    for bad in [(10, 10), (-1, 10), (1, np.inf), (1, 2, 3), "1,2", (1, True), (5, 300.0)]:
        with pytest.raises(ParameterError, match=r"^`band` must be \(f_low, f_high\) in Hz"):
            check_band(bad, nyquist=250.0)


def test_seeds():
    g = np.random.default_rng(0)
    assert check_seed(g) is g and check_seed(None) is None and check_seed(np.int32(4)) == 4
    for bad in (-1, 1.0, True, "3"):
        with pytest.raises(ParameterError):
            check_seed(bad)
    with pytest.raises(ParameterError, match="an integer >= 0; got"):
        check_seed(g, allow_generator=False)


class _Toy(Estimator):
    abstract = True  # a test double: kept out of the registry the contract test walks
    parameter_constraints = {
        "n": [Interval(int, 1, None)],
        "lam": [Interval(float, 0.0, 1.0, closed="right")],
        "mode": [Options("a", "b"), None],
        "flag": [Boolean()],
        "band": [Band(), None],
        "obj": [InstanceOf(dict, "a dict of orders"), Satisfies(lambda v: v == "auto", "'auto'")],
    }

    def __init__(self, n=3, lam=1.0, mode=None, flag=False, band=None, obj="auto"):
        self.n, self.lam, self.mode, self.flag, self.band, self.obj = n, lam, mode, flag, band, obj

    def check_together(self):
        if self.mode == "b" and self.n > 5:
            raise self.invalid("n", "at most 5 with mode 'b'")

    def fit(self, data):
        self.validate_params()
        return data


def test_base_validates_in_one_shape():
    _Toy().fit(None)
    _Toy(n=np.int64(2), lam=np.float64(0.5), mode="a", flag=np.bool_(True), band=(0, 1), obj={}).fit(None)
    cases = {
        "n": (0, "an integer >= 1"),
        "lam": (0.0, r"a number in \(0, 1\]"),
        "mode": ("c", "'a' or 'b' or None"),
        "flag": (1, "True or False"),
        "band": ((2, 1), r"\(f_low, f_high\) in Hz with 0 <= f_low < f_high finite or None"),
        "obj": ("x", "a dict of orders or 'auto'"),
    }
    for name, (value, words) in cases.items():
        with pytest.raises(ParameterError, match=rf"^`{name}` of _Toy must be {words}; got "):
            _Toy(**{name: value}).fit(None)
    with pytest.raises(ParameterError, match=r"^`n` of _Toy must be at most 5 with mode 'b'; got 6\.$"):
        _Toy(n=6, mode="b").fit(None)


def test_repr_and_params():
    t = _Toy(n=4, band=(1.0, 2.0))
    assert repr(t) == "_Toy(n=4, band=(1.0, 2.0))"
    assert t.get_params() == {"n": 4, "lam": 1.0, "mode": None, "flag": False, "band": (1.0, 2.0), "obj": "auto"}
    assert _Toy.parameter_names() == ("n", "lam", "mode", "flag", "band", "obj")


def test_memory_guard_names_need_and_availability(monkeypatch):
    from stageid import ResourceError
    from stageid.runtime.resources import available_memory, require_memory, require_work

    monkeypatch.setenv("STAGEID_MEMORY_LIMIT", "100M")
    assert available_memory() <= 100 * 2**20
    require_memory(10 * 2**20, "a small request")
    with pytest.raises(ResourceError, match=r"^a big request would need about 1 GB of memory; 80 MB is available\.$"):
        require_memory(2**30, "a big request")
    monkeypatch.setenv("STAGEID_MEMORY_LIMIT", "")
    assert available_memory() > 0
    with pytest.raises(ResourceError, match="fewer time constants"):
        require_work(1e13, 1e11, "the creep bank", "ask for fewer time constants")
