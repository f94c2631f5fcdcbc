"""Every docstring example in the package runs and prints what it says (the docs show real output)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import stageid

_MODULES = sorted(
    m.name for m in pkgutil.walk_packages(stageid.__path__, "stageid.") if not m.name.endswith("__main__")
)


@pytest.mark.parametrize("name", _MODULES)
def test_docstring_examples(name: str) -> None:
    mod = importlib.import_module(name)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} docstring examples of {name} failed"


def test_the_examples_are_found() -> None:
    # guards the test above against silently checking nothing (e.g. a packaging change)
    attempted = sum(
        doctest.testmod(importlib.import_module(n), verbose=False).attempted
        for n in ("stageid.closedloop.deduction", "stageid.plants.maglev", "stageid.hysteresis.compensator")
    )
    assert attempted >= 5
