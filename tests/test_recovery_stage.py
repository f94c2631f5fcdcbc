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
        # 13, 8 and 2 were refused ("one sampling period for all records") before the shared rule
        (13, 0),  # no dynamics, offset time column: --dynamics 1 must be dropped on held-out evidence
        (8, 0),  # creep with an offset time column
        (2, 1),  # a lag, accumulated (cumsum) time column
        (6, 2),  # a resonance and creep, fixed-decimal time column
    ],
)
def test_stage_draw_is_recovered_at_the_optimum(tmp_path, seed, order):
    row = rec_stage.case(seed, tmp_path, 0.01)
    assert row.failed == "" and row.recovered, row
    assert f"order {order}," in row.detail and f"fitted order {order}" in row.detail
    # the fit reaches the cost minimised from the truth (measured 1.0000 on all 24 draws)
    assert row.cost_ratio <= 1.0001
