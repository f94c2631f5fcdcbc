"""The bias rules on the SISO plant of tests/test_closedloop_uncertainty.py (20 seeds at 60 dB).

That plant is the fixed-seed unit test's; this prints each rule's coverage of ``|err| <= 1.73 std``
over the 20-300 Hz grid, ``E|err|^2/std^2``, and the coverage by quarter of the grid.

    .venv/bin/python studies/uncertainty_closedloop/siso_bias_rules.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from stageid.closedloop import ClosedLoopIdentification
from stageid.closedloop.uncertainty import plant_uncertainty

sys.path.insert(0, str(Path(__file__).parents[2] / "tests"))
import test_closedloop_uncertainty as T  # noqa: E402


def main() -> None:
    f = np.geomspace(20.0, 300.0, 60)
    Gt = T.G_SISO.frequency_response(f)[:, 0, 0]
    out = {r: ([], []) for r in ("flat", "local", "inflate")}
    quarters = np.array_split(np.arange(f.size), 4)
    for seed in range(20):
        res = ClosedLoopIdentification(T._siso_controller(), order_range=range(2, 9)).fit(
            T._siso_experiment(seed, 60.0)
        )
        for rule in out:
            fr = plant_uncertainty(res, f, rule)
            e, s = np.abs(fr.response[:, 0, 0] - Gt), fr.std[:, 0, 0]
            out[rule][0].append(e <= 1.73 * s)
            out[rule][1].append(e**2 / s**2)
    for rule, (hits, z2) in out.items():
        h = np.array(hits)
        by_quarter = ", ".join(f"{100 * h[:, k].mean():.1f} %" for k in quarters)
        print(f"{rule}: coverage {100 * h.mean():.1f} %, mean e^2/std^2 {np.mean(z2):.2f}; by quarter {by_quarter}")


if __name__ == "__main__":
    main()
