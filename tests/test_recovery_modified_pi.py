"""Seeded draws of the modified-PI recovery benchmark (``benchmarks/recovery/rec_modified_pi.py``)
whose deepest valley of the threshold residual is reached from one grid point only: each runs
the CLI on records with a logger's time column."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks" / "recovery"))

import rec_modified_pi  # noqa: E402
from common import draw_noise  # noqa: E402


@pytest.mark.parametrize(
    "seed",
    [
        # Gauss-Newton from the best point and the next three grid points ended at 1.30 x the
        # reference's cost (valleys at 0.149, 0.114 and the optimum 0.0878 of the weight fit's
        # residual; only the eighth grid point leads to the last)
        18,
        # the optimum's valley is 2.9 % below the one the best grid point leads to
        0,
    ],
)
def test_modified_pi_draw_is_recovered_at_the_optimum(tmp_path, seed):
    row = rec_modified_pi.case(seed, tmp_path, draw_noise(seed))  # the benchmark's draw
    assert row.failed == "" and row.recovered, row
    # the fit reaches the cost the reference minimises from the true thresholds
    assert row.cost_ratio <= 1.0001
