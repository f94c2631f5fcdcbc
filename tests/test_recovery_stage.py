"""Seeded draws of the stage recovery benchmark (``benchmarks/recovery/rec_stage.py``) that once
failed or that check a decision: each runs the CLI on records with a logger's time column."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks" / "recovery"))

import rec_stage  # noqa: E402


@pytest.mark.parametrize(
    ("seed", "order"),
    [
        (2, 0),  # no dynamics, cumsum time column: --dynamics 1 must be dropped on held-out evidence
        (3, 0),  # creep with an offset time column: refused for "one sampling period" before the shared rule
        (1, 1),  # a lag and creep, fixed-decimal time column
    ],
)
def test_stage_draw_is_recovered(tmp_path, seed, order):
    row = rec_stage.case(seed, tmp_path, 0.01)
    assert row.failed == "" and row.recovered, row
    assert f"fitted order {order}" in row.detail
    # recovered includes a cost within COST_LIMIT of the reference (measured 1.0002-1.0015 here)
    assert row.cost_ratio <= rec_stage.COST_LIMIT
