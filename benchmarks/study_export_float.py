"""How far the ``--float`` compensator lands from ``stageid compensate``, over many random models.

Run:  nice .venv/bin/python benchmarks/study_export_float.py [--models 500] [--seed 2026]
      [--samples 400] [--double] [--json out.json] [--cflags "-O2 -march=native"]

The models, drive limits and references are the stream of ``tests/test_export_c.py``
(``random_cases``: PI and modified-PI compensators with 2-24 operators, weights 0 or slightly
negative, random stored states, offsets, input warps, drive limits in 60 %; walk, sine and jump
references in turn).  For every model the compensator is exported with ``single=True``, compiled
and run on the reference, and compared with ``Compensator(model, limits).run`` in double:

* ``err``: max |C float drive - package drive| over the record, divided by the drive's scale:
  its range, at least ``2**-22 / 1e-5`` times its magnitude (the measure of
  ``tests/test_export_float.py``, see there); ``err_range`` the same over the range alone;
* ``floor``: the same for the package itself run on the reference rounded to float -- what the
  float input alone costs, which no single-precision code can avoid;
* ``arith``: max |C float drive - package drive on the float-rounded reference| / scale -- the
  float code's own arithmetic and output rounding;
* ``cond``: sum |w| / smallest slope of F, the factor by which an error in F moves the drive.

With ``--double`` the double export is checked too (1e-12 of the largest |drive|).  The figures
go in ``benchmarks/RESULTS-export.md``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from stageid.export import export_c  # noqa: E402
from stageid.export.host import build  # noqa: E402
from stageid.hysteresis import Compensator, ModifiedPIModel  # noqa: E402
from test_export_c import random_cases  # noqa: E402
from test_export_float import float_tolerance  # noqa: E402


def conditioning(model) -> float:
    """sum |w| over the smallest slope of F (modified PI) or of the inverse's sum (classical PI)."""
    w = np.asarray(model.weights, dtype=float)
    smin = model.min_slope() if isinstance(model, ModifiedPIModel) else float(np.min(np.cumsum(w)))
    return float(np.sum(np.abs(w)) / smin)


def one_case(k, model, limits, y, folder: Path, double: bool, flags: tuple[str, ...] = ("-O2",)) -> dict:
    comp = Compensator(model, limits)
    drive = comp.run(y)[:, 0]
    drive_in_f = Compensator(model, limits).run(y.astype(np.float32).astype(float))[:, 0]
    drive_c = build(export_c(model, f"f{k}", inverse=True, limits=limits, single=True), folder, flags=flags).run(y)[
        :, 0
    ]
    scale = float_tolerance(drive) / 1e-5  # the range, or the floor of a (nearly) constant drive
    span = float(np.ptp(drive))
    row = {
        "model": k,
        "kind": type(model).__name__,
        "n_operators": int(model.n_operators),
        "warp": float(getattr(model, "input_warp", 0.0)),
        "limits": limits,
        "cond": conditioning(model),
        "range": float(np.ptp(drive)),
        "scale": scale,
        "err": float(np.max(np.abs(drive_c - drive)) / scale),
        "err_range": float(np.max(np.abs(drive_c - drive)) / span) if span > 0 else float("inf"),
        "floor": float(np.max(np.abs(drive_in_f - drive)) / scale),
        "arith": float(np.max(np.abs(drive_c - drive_in_f)) / scale),
    }
    if double:
        drive_d = build(export_c(model, f"d{k}", inverse=True, limits=limits), folder).run(y)[:, 0]
        row["err_double"] = float(np.max(np.abs(drive_d - drive)) / max(float(np.max(np.abs(drive))), 1e-300))
    return row


def summary(rows: list[dict]) -> str:
    err = np.array([r["err"] for r in rows])
    strict = np.array([r["err_range"] for r in rows])
    floored = sum(r["scale"] > r["range"] for r in rows)
    lines = [
        f"models: {len(rows)}; float within 1e-5: {int(np.sum(err <= 1e-5))}; "
        f"of the range alone: {int(np.sum(strict <= 1e-5))}; constant drives (range 0): "
        f"{sum(r['range'] == 0.0 for r in rows)}; measured against the floor: {floored}",
    ]
    for key in ("err", "floor", "arith"):
        v = np.array([r[key] for r in rows])
        q = np.quantile(v, [0.5, 0.9, 0.99])
        lines.append(f"{key:6s} median {q[0]:.2e}  p90 {q[1]:.2e}  p99 {q[2]:.2e}  max {v.max():.2e}")
    if "err_double" in rows[0]:
        d = np.array([r["err_double"] for r in rows])
        lines.append(f"double: within 1e-12 {int(np.sum(d <= 1e-12))} of {len(d)}; max {d.max():.2e}")
    lines.append("worst float models (err / floor / arith / cond / kind / operators / range):")
    for r in sorted(rows, key=lambda r: -r["err"])[:8]:
        lines.append(
            f"  {r['model']:4d}  {r['err']:.2e}  {r['floor']:.2e}  {r['arith']:.2e}  {r['cond']:7.1f}  "
            f"{r['kind']}  {r['n_operators']}  {r['range']:.3g}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=int, default=500)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--samples", type=int, default=400)
    ap.add_argument("--double", action="store_true", help="also check the double export")
    ap.add_argument("--json", type=Path, help="write every model's figures here")
    ap.add_argument("--cflags", default="-O2", help="flags of the float build (-march=native: fmaf products)")
    args = ap.parse_args(argv)
    cases = random_cases(args.seed, range(args.models), args.samples)
    rows = []
    with tempfile.TemporaryDirectory(prefix="study_float_") as tmp:
        for k, (model, limits, y) in cases.items():
            rows.append(one_case(k, model, limits, y, Path(tmp), args.double, tuple(shlex.split(args.cflags))))
            for lib in Path(tmp).glob("*"):  # one model at a time: keep the folder small
                lib.unlink()
    print(f"# seed {args.seed}, {args.models} models, references of {args.samples} samples; {args.cflags}")
    print(summary(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
