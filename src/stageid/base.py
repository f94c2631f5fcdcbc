"""The estimator contract: parameters declared once, checked in one place, a frozen result.

Every estimator of stageid derives from :class:`Estimator`:

* ``__init__`` takes keyword hyper-parameters and stores each unchanged under its own name;
  it does no work and no checks;
* ``parameter_constraints`` declares, for every parameter of ``__init__``, the values it
  accepts (a list of :class:`Constraint` objects or ``None``; a value satisfying any of them
  is valid);
* ``fit(data)`` first calls :meth:`Estimator.validate_params`, which raises one
  :class:`~stageid.ParameterError` shape for every estimator (the first failing parameter)::

      `horizon` of HankelMAP must be an integer >= 1 or 'auto'; got -3.

  and then returns a frozen result that keeps no training data; the caller's data are never
  modified, and a second ``fit`` gives an independent result;
* :meth:`~Estimator.get_params` and ``repr`` (which shows the non-default parameters) come
  from the declaration.

Subclasses register themselves: :func:`estimators` lists every concrete estimator, which is
how the contract test (``tests/test_contract_estimators.py``) finds them without a
hand-written list.  The shape follows scikit-learn's ``utils/_param_validation.py``.
"""

from __future__ import annotations

import copy
import functools
import inspect
import warnings
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from ._errors import ParameterError
from .checks import check_band, describe_interval, in_interval, is_integer, is_real, shown

__all__ = [
    "Estimator",
    "Constraint",
    "Interval",
    "Options",
    "InstanceOf",
    "Boolean",
    "Band",
    "Satisfies",
    "estimators",
]


class Constraint:
    """A set of accepted values with the words that describe it in messages."""

    def accepts(self, value: Any) -> bool:
        raise NotImplementedError

    def __str__(self) -> str:
        raise NotImplementedError


class Interval(Constraint):
    """Reals (``kind=float``) or integers (``kind=int``) between ``low`` and ``high``.

    ``closed`` is ``"both"``, ``"left"``, ``"right"`` or ``"neither"``; ``None`` ends are
    open.  ``bool``, strings and non-finite values are never accepted.
    """

    def __init__(self, kind: type, low: float | None, high: float | None, closed: str = "both") -> None:
        self.kind, self.low, self.high, self.closed = kind, low, high, closed

    def accepts(self, value: Any) -> bool:
        if not (is_integer(value) if self.kind is int else is_real(value)):
            return False
        v = float(value) if self.kind is not int else int(value)
        return in_interval(v, self.low, self.high, self.closed)

    def __str__(self) -> str:
        return describe_interval(self.low, self.high, self.closed, integer=self.kind is int)


class Options(Constraint):
    """One of a closed set of lowercase strings."""

    def __init__(self, *options: str) -> None:
        self.options = options

    def accepts(self, value: Any) -> bool:
        return isinstance(value, str) and value in self.options

    def __str__(self) -> str:
        return (
            " or ".join(repr(o) for o in self.options)
            if len(self.options) <= 2
            else ("one of " + ", ".join(repr(o) for o in self.options))
        )


class InstanceOf(Constraint):
    """An instance of ``types`` (described by ``words``, default "a <TypeName>")."""

    def __init__(self, types: type | tuple[type, ...], words: str | None = None) -> None:
        self.types = types
        names = types if isinstance(types, tuple) else (types,)
        self.words = words or " or ".join(f"a {t.__name__}" for t in names)

    def accepts(self, value: Any) -> bool:
        return isinstance(value, self.types)

    def __str__(self) -> str:
        return self.words


class Boolean(Constraint):
    """``True`` or ``False`` (Python or numpy booleans; never 0/1)."""

    def accepts(self, value: Any) -> bool:
        import numpy as np

        return isinstance(value, (bool, np.bool_))

    def __str__(self) -> str:
        return "True or False"


class Band(Constraint):
    """A frequency band by the one rule of :func:`stageid.checks.check_band`."""

    def accepts(self, value: Any) -> bool:
        try:
            check_band(value)
        except ParameterError:
            return False
        return True

    def __str__(self) -> str:
        return "(f_low, f_high) in Hz with 0 <= f_low < f_high finite"


class Satisfies(Constraint):
    """Values for which ``predicate`` is true, described by ``words``."""

    def __init__(self, predicate: Callable[[Any], bool], words: str) -> None:
        self.predicate, self.words = predicate, words

    def accepts(self, value: Any) -> bool:
        try:
            return bool(self.predicate(value))
        except (TypeError, ValueError, OverflowError):
            return False

    def __str__(self) -> str:
        return self.words


_REGISTRY: dict[str, type[Estimator]] = {}


def estimators() -> dict[str, type[Estimator]]:
    """Every concrete estimator class, by qualified name (imports every stageid package).

    A class is concrete when it defines ``fit`` and is not marked ``abstract = True``.
    """
    import importlib
    import pkgutil

    import stageid

    for info in pkgutil.walk_packages(stageid.__path__, "stageid."):
        if ".cli" in info.name or info.name.endswith("__main__"):
            continue  # the command line and module mains register nothing
        importlib.import_module(info.name)
    return dict(_REGISTRY)


class Estimator:
    """Base of every estimator: declared parameters, one validator, ``get_params``, ``repr``.

    Subclasses set ``parameter_constraints`` (parameter name -> list of constraints, ``None``
    in the list accepting ``None``) for every ``__init__`` parameter, store every parameter
    unchanged in ``__init__``, and call :meth:`validate_params` at the start of ``fit``.
    Rules that tie two parameters together go in :meth:`check_together`, which raises through
    :meth:`invalid` so the message keeps the one shape.
    """

    parameter_constraints: ClassVar[Mapping[str, list[Any]]] = {}
    abstract: ClassVar[bool] = True
    #: Former keyword -> its parameter now: a name, or ``(name, i)`` for end ``i`` of a pair
    #: (``{"fmin": ("band", 0)}``).  A former keyword still works, with a DeprecationWarning.
    renamed_parameters: ClassVar[Mapping[str, str | tuple[str, int]]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if not cls.__dict__.get("abstract", False):
            cls.abstract = False
            _REGISTRY[f"{cls.__module__}.{cls.__qualname__}"] = cls
        if cls.renamed_parameters and "__init__" in cls.__dict__:  # a subclass's own __init__ too
            cls.__init__ = _accepting_former_names(cls.__init__, cls.renamed_parameters)

    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        """The ``__init__`` parameters, in their order."""
        sig = inspect.signature(cls.__init__)
        return tuple(
            n
            for n, p in sig.parameters.items()
            if n != "self" and p.kind not in (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
        )

    def get_params(self) -> dict[str, Any]:
        """The hyper-parameters as a dict, in ``__init__`` order."""
        return {name: getattr(self, name) for name in self.parameter_names()}

    def clone(self) -> Estimator:
        """A new estimator of the same class with copies of the same settings.

        What a result keeps of its estimator: changing the estimator after a fit then changes
        neither the result nor what its ``update`` does.
        """
        return type(self)(**copy.deepcopy(self.get_params()))

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__)
        shown = []
        for name, value in self.get_params().items():
            default = sig.parameters[name].default
            if default is inspect.Parameter.empty or not _same(value, default):
                shown.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(shown)})"

    def invalid(self, name: str, expected: str) -> ParameterError:
        """The error for parameter ``name``: "`name` of Class must be <expected>; got <value>."."""
        value = shown(getattr(self, name, None))
        return ParameterError(f"`{name}` of {type(self).__name__} must be {expected}; got {value}.")

    def validate_params(self) -> None:
        """Check every declared parameter, then :meth:`check_together`; raise ParameterError."""
        for name, constraints in self.parameter_constraints.items():
            value = getattr(self, name)
            if any(value is None if c is None else c.accepts(value) for c in constraints):
                continue
            words = [("None" if c is None else str(c)) for c in constraints]
            expected = words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]
            raise self.invalid(name, expected)
        self.check_together()

    def check_together(self) -> None:
        """Rules tying several parameters together (override; raise ``self.invalid(...)``)."""

    def fit(self, data: Any) -> Any:  # pragma: no cover - every concrete estimator overrides it
        raise NotImplementedError


def _accepting_former_names(init: Callable, renamed: Mapping[str, str | tuple[str, int]]) -> Callable:
    """``init`` that maps former keywords to their parameters, warning once per call."""

    @functools.wraps(init)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> None:
        pairs: dict[str, list[Any]] = {}
        for old in [k for k in kwargs if k in renamed]:
            new = renamed[old]
            value = kwargs.pop(old)
            name = new if isinstance(new, str) else new[0]
            if name in kwargs:
                raise ParameterError(f"`{old}` is the former name of `{name}`; give only `{name}`.")
            if isinstance(new, str):
                kwargs[new] = value
            else:
                pairs.setdefault(name, [None, None])[new[1]] = value
            warnings.warn(
                f"`{old}` of {type(self).__name__} is now `{name}`; the former name will be removed.",
                DeprecationWarning,
                stacklevel=2,
            )
        for name, pair in pairs.items():
            kwargs[name] = tuple(pair)
        init(self, *args, **kwargs)

    return wrapper


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a is b or (type(a) is type(b) and a == b))
    except (TypeError, ValueError):  # arrays compare elementwise
        return False
