"""Old module paths of moved modules (stageid._moved.MOVED) import the module at its new path."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from stageid._moved import MOVED


@pytest.mark.parametrize(("old", "new"), sorted(MOVED.items()))
def test_old_path_is_the_new_module(old, new):
    # the very same object: monkeypatching through the old path must reach the code that runs
    assert importlib.import_module(old) is importlib.import_module(new)
    assert importlib.import_module(new).__spec__.name == new  # not the alias's spec


def test_no_file_is_left_at_an_old_path():
    # the finder runs first, so a stale file there would never run, only mislead its readers
    import stageid

    root = Path(stageid.__file__).parent
    for old in MOVED:
        rel = Path(*old.split(".")[1:])
        assert not (root / rel / "__init__.py").exists(), old
        assert not (root / rel.with_suffix(".py")).exists(), old


def test_from_import_of_an_old_path_in_a_fresh_interpreter():
    code = "from stageid.frf.frd import FrequencyResponse; print(FrequencyResponse.__module__)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "stageid.models.frequency_response"
