"""Record the prediction-error fits of one recovery draw, and replay them with the installed package.

    python benchmarks/recovery/pem_fit_replay.py record --module rec_pem --seed 4 --out fits4.pkl
    python benchmarks/recovery/pem_fit_replay.py replay fits4.pkl

``record`` runs one draw of a ``rec_*`` module (the PEM or closed-loop case) and keeps the arguments
and result of every :func:`stageid.closedloop.pem.fit_pem` call it makes (the order climbs, the
level passes and the refits of ``identify closed-loop``); ``replay`` fits each recorded problem
again with whatever package is on the path and prints the CPU seconds, the loss evaluations and the
per-fit loss against the recorded one.  An optimiser change is thus measured on the very problems
of a draw in a fraction of the draw's time, fit by fit; whether it keeps a draw recovered is then
the draw's own question (``run.py``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one BLAS thread: CPU seconds comparable between runs

import argparse  # noqa: E402
import importlib  # noqa: E402
import pathlib  # noqa: E402
import pickle  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402

import numpy as np  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
for _p in (HERE, HERE.parent):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def record(module: str, seed: int, out: pathlib.Path) -> None:
    """Run draw ``seed`` of ``module`` and pickle ``[(args, kwargs, model), ...]`` of its fits."""
    from run import draw_noise

    pem_mod = importlib.import_module("stageid.closedloop.pem")
    selection = importlib.import_module("stageid.closedloop.order_selection")
    original = pem_mod.fit_pem
    calls = []

    def recording(*args, **kwargs):
        model = original(*args, **kwargs)
        calls.append((args, kwargs, model))
        return model

    pem_mod.fit_pem = selection.fit_pem = recording  # pem() and the order climbs look the name up here
    try:
        with tempfile.TemporaryDirectory() as tmp:
            row = importlib.import_module(module).case(seed, pathlib.Path(tmp), draw_noise(seed))
    finally:
        pem_mod.fit_pem = selection.fit_pem = original
    out.write_bytes(pickle.dumps(calls))
    print(f"{module} seed {seed}: recovered {row.recovered}, error {row.error:.4g}, cost ratio {row.cost_ratio:.4g}")
    print(f"{len(calls)} fits, {sum(m.n_iterations for _, _, m in calls)} loss evaluations -> {out}")


def replay(path: pathlib.Path) -> None:
    """Fit every recorded problem again; CPU seconds, evaluations and loss ratios to the recording."""
    pem_mod = importlib.import_module("stageid.closedloop.pem")
    calls = pickle.loads(path.read_bytes())
    ratios, evaluations, seconds = [], 0, 0.0
    for args, kwargs, recorded in calls:
        t0 = _cpu()
        try:
            model = pem_mod.fit_pem(*args, **kwargs)
            ratios.append(model.loss / recorded.loss)
            evaluations += model.n_iterations
        except Exception:  # noqa: BLE001 - a refused fit counts as lost, whatever the reason
            ratios.append(np.inf)
        seconds += _cpu() - t0
    r = np.array(ratios)
    print(
        f"{path.name}: {len(calls)} fits, CPU {seconds:.1f} s, {evaluations} loss evaluations "
        f"(recorded {sum(m.n_iterations for _, _, m in calls)}); loss / recorded loss: median {np.median(r):.5f}, "
        f"max {r.max():.4g}, min {r.min():.4g}; {int(np.sum(r > 1.001))} fits above 1.001, "
        f"{int(np.sum(r < 0.999))} below 0.999"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("--module", default="rec_pem")
    rec.add_argument("--seed", type=int, required=True)
    rec.add_argument("--out", type=pathlib.Path, required=True)
    rep = sub.add_parser("replay")
    rep.add_argument("paths", type=pathlib.Path, nargs="+")
    args = p.parse_args(argv)
    if args.command == "record":
        record(args.module, args.seed, args.out)
    else:
        for path in args.paths:
            replay(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
