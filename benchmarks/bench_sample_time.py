"""The sample-time rule on time columns as loggers write them: how often the period comes out
other than 1/fs, before (end-to-end step) and with the rule (least-squares period), over 200
random record lengths per style; and the time to read a long column.

    PYTHONPATH=src python benchmarks/bench_sample_time.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent / "recovery"))
from common import TIME_STYLES, time_column  # noqa: E402

from stageid.data.sampling import time_grid  # noqa: E402


def main() -> None:
    rng = np.random.default_rng(0)
    lengths = rng.integers(500, 30000, 200)
    for fs in (1e4, 7e3):
        for style in TIME_STYLES:
            ends = rule = 0
            worst = 0.0
            for n in lengths:
                n = int(n) // 2 if style == "float32" and n > 20000 else int(n)  # float32: short records only
                t = np.array([float(v) for v in time_column(n, fs, style, rng)])
                ends += (t[-1] - t[0]) / (n - 1) != 1.0 / fs
                dt = time_grid(t).dt
                rule += dt != 1.0 / fs
                worst = max(worst, abs(dt * fs - 1.0))
            print(
                f"fs {fs:6.0f} Hz  {style:8s} end-to-end step off 1/fs: {ends:3d}/200   rule: {rule:3d}/200 (worst {worst:.1e})"
            )
    for name, t in (("repr", np.arange(2_000_000) / 1e4), ("fixed 7 kHz", np.round(np.arange(2_000_000) / 7e3, 6))):
        time_grid(t)
        start = time.perf_counter()
        time_grid(t)
        print(f"time_grid of 2e6 stamps ({name}): {time.perf_counter() - start:.3f} s")


if __name__ == "__main__":
    main()
