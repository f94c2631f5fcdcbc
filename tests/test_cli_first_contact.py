"""A new user's first commands: what they are told when a record does not fit the model or the
command, and what the commands print where."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import run_main
from stageid.data.io import read_table, write_csv
from stageid.models import StateSpaceModel, save_model


@pytest.fixture
def two_input_model(tmp_path):
    """A stable discrete 3-state model with inputs Z, Rx and outputs z, rx."""
    rng = np.random.default_rng(5)
    A = rng.standard_normal((3, 3))
    A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))
    g = StateSpaceModel(
        A,
        rng.standard_normal((3, 2)),
        rng.standard_normal((2, 3)),
        np.zeros((2, 2)),
        dt=0.01,
        inputs=("Z", "Rx"),
        outputs=("z", "rx"),
    )
    save_model(g, tmp_path / "g.json")
    return g


def test_simulate_names_the_inputs_a_record_lacks(tmp_path, two_input_model):
    write_csv(tmp_path / "z.csv", {"Z": np.ones(100)}, dt=0.01)
    code, out, err = run_main("simulate", "g.json", "z.csv", "-o", "y.csv", cwd=tmp_path)
    assert code == 2 and not (tmp_path / "y.csv").exists()
    assert "input(s) Rx" in err and "its columns: Z" in err and "--zero-missing" in err and len(err.splitlines()) == 1


def test_simulate_zero_missing_holds_the_absent_inputs_at_zero_and_says_so(tmp_path, two_input_model):
    u = np.random.default_rng(6).standard_normal(200)
    write_csv(tmp_path / "z.csv", {"Z": u}, dt=0.01)
    code, out, err = run_main("simulate", "g.json", "z.csv", "--zero-missing", "-o", "y.csv", cwd=tmp_path)
    assert code == 0, err
    assert "Rx" in err and "held at 0" in err
    expected = two_input_model.simulate(np.column_stack([u, np.zeros_like(u)]))
    np.testing.assert_allclose(read_table(tmp_path / "y.csv").values, expected, atol=1e-9)
