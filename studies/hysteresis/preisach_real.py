"""The Preisach model on the dSPACE piezo records (issue 16, section 4c of RESULTS.md).

Run: ``OMP_NUM_THREADS=1 python studies/hysteresis/preisach_real.py``; prints a Markdown table.

Identified on the 20 Hz and 100 Hz FORC records together (rate independent, one offset per
record), validated on the 40 Hz FORC and the six 2 s tracking records.  Every record gets its
own sensor zero (mean residual) and the best of the three starting states (``zero``:
demagnetised about the first input, ``ascending``, ``descending``), as in ``stage_study.py``;
the model is untouched.  The records are trimmed as in ``run_study.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
NAMES = ["20_hz_no_lp", "40_hz_no_lp", "100_hz_no_lp", "tri50_1", "tri100_1", "sine50_1", "sine100_1"]
NAMES += ["prbn_1", "bigsine_1"]


def aligned_errors(model, u, y):
    """(max, RMS) error in % of the record's range with its own offset and best start."""
    best = None
    for kind in ("zero", "ascending", "descending"):
        e = y - model.with_state(model.consistent_state(u[0], kind)).simulate(u)[:, 0]
        e = e - e.mean()
        cand = (float(np.sqrt(np.mean(e**2))), float(np.abs(e).max()))
        best = cand if best is None or cand[0] < best[0] else best
    return 100 * best[1] / np.ptp(y), 100 * best[0] / np.ptp(y)


def main() -> int:
    sys.path.insert(0, str(HERE))
    from run_study import _trim_dspace

    from stageid.data.datasets import load_dspace_piezo, shared_data_dir
    from stageid.hysteresis import PIIdentifier, PreisachIdentifier

    root = shared_data_dir()
    folder = None if root is None else root / "piezo_dspace_preisach"
    if folder is None or not folder.is_dir():
        print("dSPACE records not found; skipped")
        return 0
    recs = {n: _trim_dspace(load_dspace_piezo(folder / f"{n}.mat")) for n in NAMES}
    train = [recs["20_hz_no_lp"], recs["100_hz_no_lp"]]
    fits = {}
    for label, est in (
        ("modified PI 20", PIIdentifier("modified-pi", n_operators=20)),
        ("Preisach 15", PreisachIdentifier(n_levels=15)),
        ("Preisach 20", PreisachIdentifier(n_levels=20)),
        ("Preisach 25", PreisachIdentifier(n_levels=25)),
    ):
        t0 = time.perf_counter()
        try:
            fits[label] = est.fit(train).model
        except Exception as exc:  # a grid the records do not resolve: say so in the table
            print(f"{label}: {exc}")
            continue
        print(f"{label}: fit {time.perf_counter() - t0:.1f} s")
    print("\n| record | " + " | ".join(fits) + " |")
    print("|---|" + "---|" * len(fits))
    for n in NAMES:
        u, y = recs[n]
        cells = [aligned_errors(m, u, y) for m in fits.values()]
        print(f"| {n} | " + " | ".join(f"{a:.2f} / {b:.2f}" for a, b in cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
