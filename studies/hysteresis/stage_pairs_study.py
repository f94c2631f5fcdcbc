"""The stage recipe trained on each pair of the dSPACE FORC records, validated on the tracking records.

Run: ``OMP_NUM_THREADS=1 python studies/hysteresis/stage_pairs_study.py [--modes auto|spectrum]
[--pair A+B ...] [--order N --creep TAU ...]``; prints one Markdown row per pair (the table of ``studies/hysteresis/RESULTS.md``
sections 4h-4j).

The recipe is the one a user passes for a rate-dependent stage per the README:
``stageid identify hysteresis A.csv B.csv --input V --output y --model preisach --dynamics auto
--creep auto`` (here the same estimator called with the same settings,
``StageIdentifier("preisach", dynamics="auto", creep="auto", disturbance_modes=MODES)``), then
``stageid validate``'s default, ``validate_record(..., "estimate")`` on every tracking record:
RMS error in % of the record's range.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DT = 1e-4
PAIRS = ("20_hz_no_lp+40_hz_no_lp", "20_hz_no_lp+100_hz_no_lp", "40_hz_no_lp+100_hz_no_lp")
TRACKING = ("tri50_1", "tri100_1", "sine50_1", "sine100_1", "prbn_1", "bigsine_1")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", default="auto", choices=("auto", "spectrum"))
    parser.add_argument("--pair", action="append", default=None)
    parser.add_argument("--order", type=int, default=None, help="a fixed order instead of auto")
    parser.add_argument("--creep", type=float, nargs="+", default=None, help="fixed creep time constants [s]")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(HERE.parents[1] / "tests"))
    from _dspace_records import dspace_record
    from stageid.hysteresis.stage.identification import StageIdentifier
    from stageid.hysteresis.stage.validation import validate_record

    print("| pair | " + " | ".join(TRACKING) + " | order / creep / modes | seconds |")
    print("|---" * (len(TRACKING) + 3) + "|")
    for pair in args.pair or PAIRS:
        train = [dspace_record(n)[:2] for n in pair.split("+")]
        start = time.process_time()
        dynamics = "auto" if args.order is None else args.order
        creep = "auto" if args.creep is None else tuple(args.creep)
        est = StageIdentifier("preisach", dynamics=dynamics, creep=creep, sample_time=DT, disturbance_modes=args.modes)
        fit = est.fit(train)
        seconds = time.process_time() - start
        rms = [validate_record(fit.model, *dspace_record(n), "estimate").rms_error_percent for n in TRACKING]
        modes = ", ".join(f"{m.frequency_hz:.0f} Hz / {m.damping:.3f}" for m in fit.modes) or "none"
        taus = "/".join(f"{t:g}" for t in fit.creep_time_constants) or "none"
        cells = " | ".join(f"{r:.2f}" for r in rms)
        print(f"| {pair} | {cells} | {fit.dynamics_order} / {taus} s / {modes} | {seconds:.0f} |", flush=True)
        print(f"<!-- {fit.message} -->", flush=True)


if __name__ == "__main__":
    main()
