"""Tests that kill surviving mutants of ``subspace/result.py`` (tests/MUTATION.md)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from stageid.subspace import HankelMAP

sys.path.insert(0, str(Path(__file__).parent))
from _subspace_systems import random_stage, record  # noqa: E402


def test_per_channel_markov_parameters_are_assembled_column_by_column() -> None:
    g = random_stage(3, m=2, q=2, modes=2)
    exps = []
    for j in range(2):  # one record per input, only that input moving (per_channel's rule)
        u = np.zeros((2000, 2))
        u[:, j] = np.random.default_rng(j).standard_normal(2000)
        exps.append(record(g, u, 0.001, j, names=False))
    res = HankelMAP(horizon=10, order=[4, 4], per_channel=True).fit(exps)
    mean, sd = res.markov_parameters(8)
    assert mean.shape == sd.shape == (8, 2, 2)
    true = g.markov_parameters(8)
    assert np.abs(mean - true).max() < 1e-3 * np.abs(true).max()  # measured 2.9e-4: both columns


def test_markov_parameters_of_a_two_input_fit_take_each_inputs_columns() -> None:
    g = random_stage(3, m=2, q=2, modes=2)
    u = np.random.default_rng(5).standard_normal((2000, 2))  # both inputs at once: m = 2 in one posterior
    mean, sd = HankelMAP(horizon=10, order=4).fit(record(g, u, 0.001, 5, names=False)).markov_parameters(8)
    true = g.markov_parameters(8)
    assert mean.shape == sd.shape == (8, 2, 2) and np.all(sd > 0)
    assert np.abs(mean - true).max() < 1e-3 * np.abs(true).max()
