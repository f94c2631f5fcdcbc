"""Closed-loop identification, two source trees side by side: alternating rounds, medians, ratios.

Each tree gets one long-lived worker process (``PYTHONPATH=<tree>/src``, one BLAS thread) that
builds the cases once and then times ``ClosedLoopIdentification.fit`` on request; the workers
take turns case by case and round by round, so that the load of a shared machine falls on both
alike.  Besides the times (wall and process CPU) every worker reports the accuracy of its model
against the true plant (basis-invariant: frequency responses over 20-300 Hz and the unstable
poles), and the report says whether the two trees' plant responses are equal.

Cases: ``maglev`` (the reference stage of Shakir & Kim, three chirp records, as in the demo;
``maglev-s<seed>`` with noise seeds ``seed, seed + 1, seed + 2`` instead of 0, 1, 2) and
``2x2-s<seed>`` (the test plant of ``tests/_closedloop_plant2x2.py``, one 1 um chirp per
axis at 70 dB SNR, as in the CLI test; ``2x2-s<seed>-<snr>db`` for another SNR); ``pem-oe``,
``pem-armax`` and ``pem-bj`` time the stageid PEM runs of ``bench_closedloop.py`` (fit = its
simulation fit on the validation record).

    .venv/bin/python benchmarks/bench_closedloop_sidebyside.py --old /tmp/old/src --new src [--rounds 7]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CASES = ("maglev", "2x2-s10", "2x2-s20")


# ------------------------------------------------------------------------------ worker side
def _build(case: str):
    """``(estimator, experiments, true continuous plant)`` of one case."""
    from stageid.closedloop import ClosedLoopIdentification

    if case == "maglev" or case.startswith("maglev-s"):
        from stageid.plants import maglev

        outs = list(maglev.OUTPUTS)
        refs = [f"r_{o}" for o in outs]
        seed0 = int(case.split("-s")[1]) if "-s" in case else 0  # noise seeds seed0, seed0 + 1, seed0 + 2
        tables = [maglev.simulate_chirp(a, seed=seed0 + k) for k, a in enumerate(outs)]
        exps = [t.experiment(refs, outs, name=f"chirp-{a}") for t, a in zip(tables, outs)]
        return ClosedLoopIdentification(maglev.controller(), band=(20.0, 300.0)), exps, maglev.model()
    sys.path.insert(0, str(HERE.parent / "tests"))
    import _closedloop_plant2x2 as p2

    spec = case.split("-s")[1].split("-")  # "2x2-s<seed>" or "2x2-s<seed>-<snr>db"
    seed, snr = int(spec[0]), (float(spec[1].removesuffix("db")) if len(spec) > 1 else 70.0)
    exps = p2.chirp_experiments((seed, seed + 1), snr)
    return ClosedLoopIdentification(p2.controller(), band=(20.0, 300.0)), exps, p2.plant()


def _accuracy(res, true) -> dict:
    f = np.geomspace(20.0, 300.0, 300)
    Gt, Gh = true.frequency_response(f), res.plant.frequency_response(f)
    rel = np.max(np.abs(Gh - Gt) / np.abs(Gt), axis=0)
    peak = np.max(np.abs(Gh - Gt), axis=0) / np.max(np.abs(Gt), axis=0)
    off = ~np.eye(rel.shape[0], dtype=bool)
    rhp = np.sort(np.asarray(res.plant_unstable_poles).real)
    true_rhp = np.sort([p.real for p in true.poles() if p.real > 1e-6])
    return {
        "diag_error_percent": [float(100 * rel[k, k]) for k in range(rel.shape[0])],
        "coupling_error_of_peak_max_percent": float(100 * np.max(peak[off])),
        "rhp_pole_error_max_percent": float(100 * max(np.min(np.abs(rhp - t)) / t for t in true_rhp)),
        "response": [Gh.real.tolist(), Gh.imag.tolist()],
        "orders": [int(res.pem_models[k].F.size - 1) for k in sorted(res.pem_models)],
    }


def _pem_case(case: str):
    """``(fit, accuracy)`` of a ``pem-<structure>`` case: the PEM runs of ``bench_closedloop.py``."""
    sys.path.insert(0, str(HERE))
    import bench_closedloop as bc

    from stageid.closedloop import pem

    r, y, _ = bc.data(0, 2.0)
    rv, _, yv0 = bc.data(1, 1.5)
    n, structure = bc.N_ORDER, case.split("-")[1]
    orders = {
        "oe": {"nb": n, "nf": n},
        "armax": {"na": n, "nb": n, "nc": n},
        "bj": {"nb": n, "nf": n, "nc": 2, "nd": 2},
    }
    fit = lambda: pem(1e6 * r, 1e6 * y, structure, orders[structure], nk=1, dt=bc.DT)  # noqa: E731
    return fit, lambda m: {"fit_percent": bc.fit_percent(1e6 * yv0, m.simulate(1e6 * rv)), "response": m.B.tolist()}


def worker() -> None:
    """Answer ``case`` lines on stdin with one JSON line of timings and accuracy."""
    built = {}
    for line in sys.stdin:
        case = line.strip()
        if not case:
            continue
        if case not in built:
            if case.startswith("pem-"):
                built[case] = _pem_case(case)
            else:
                est, exps, true = _build(case)
                built[case] = (lambda est=est, exps=exps: est.fit(exps)), (lambda res, true=true: _accuracy(res, true))
        fit, accuracy = built[case]
        t0, c0 = time.perf_counter(), time.process_time()
        res = fit()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(json.dumps({"case": case, "wall": wall, "cpu": cpu, **accuracy(res)}), flush=True)


# ------------------------------------------------------------------------------ driver side
def _spawn(src: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(Path(src).resolve()), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen(
        [sys.executable, __file__, "--worker"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
    )


def _ask(proc: subprocess.Popen, case: str) -> dict:
    proc.stdin.write(case + "\n")
    proc.stdin.flush()
    return json.loads(proc.stdout.readline())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--old", help="the old tree's src directory")
    ap.add_argument("--new", default=str(HERE.parent / "src"), help="the new tree's src directory")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--cases", nargs="+", default=list(CASES))
    args = ap.parse_args()
    if args.worker:
        worker()
        return
    if not args.old:
        ap.error("--old is required")
    procs = {"old": _spawn(args.old), "new": _spawn(args.new)}
    load = [os.getloadavg()[0]]
    runs: dict[tuple[str, str], list[dict]] = {}
    for case in args.cases:  # one untimed warm-up per worker and case (imports, numba cache, first calls)
        for name in ("old", "new"):
            _ask(procs[name], case)
    for rnd in range(args.rounds):
        for case in args.cases:
            order = ("old", "new") if rnd % 2 == 0 else ("new", "old")
            for name in order:
                runs.setdefault((case, name), []).append(_ask(procs[name], case))
                load.append(os.getloadavg()[0])
        print(f"round {rnd + 1}/{args.rounds} done, load {load[-1]:.1f}", file=sys.stderr, flush=True)
    for p in procs.values():
        p.stdin.close()
        p.wait()
    print(report(runs, args, load))


def report(runs, args, load) -> str:
    lines = [
        f"Side by side, {args.rounds} alternating rounds (1 untimed warm-up each), one BLAS thread; "
        f"1-minute load average {min(load):.1f}-{max(load):.1f} (median {np.median(load):.1f}) on {os.cpu_count()} cores.",
        "",
        "| case | old wall [s] | new wall [s] | old/new wall | median paired ratio | old CPU [s] | new CPU [s] | old/new CPU |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for case in args.cases:
        o, n = runs[(case, "old")], runs[(case, "new")]
        ow, nw = np.median([r["wall"] for r in o]), np.median([r["wall"] for r in n])
        oc, nc = np.median([r["cpu"] for r in o]), np.median([r["cpu"] for r in n])
        paired = np.median([a["wall"] / b["wall"] for a, b in zip(o, n)])
        lines.append(
            f"| {case} | {ow:.2f} | {nw:.2f} | {ow / nw:.2f}x | {paired:.2f}x | {oc:.2f} | {nc:.2f} | {oc / nc:.2f}x |"
        )
    lines += [
        "",
        "| case | tree | diagonal error [%] | coupling error of peak, max [%] | RHP pole error, max [%] | PEM orders |",
        "|---|---|---|---|---|---|",
    ]
    for case in args.cases:
        if case.startswith("pem-"):
            fits = [runs[(case, k)][-1]["fit_percent"] for k in ("old", "new")]
            lines.append(f"| {case} | old / new | simulation fit {fits[0]:.4f} / {fits[1]:.4f} % | | | |")
            continue
        for name in ("old", "new"):
            r = runs[(case, name)][-1]
            diag = ", ".join(f"{v:.4f}" for v in r["diag_error_percent"])
            lines.append(
                f"| {case} | {name} | {diag} | {r['coupling_error_of_peak_max_percent']:.3f} | "
                f"{r['rhp_pole_error_max_percent']:.4f} | {' '.join(map(str, r['orders']))} |"
            )
        ro, rn = (np.array(runs[(case, k)][-1]["response"]) for k in ("old", "new"))
        if np.array_equal(ro, rn):
            lines.append(f"| {case} | | plant responses of the two trees bitwise equal | | | |")
        else:
            go, gn = ro[0] + 1j * ro[1], rn[0] + 1j * rn[1]
            rel = float(np.max(np.abs(gn - go) / np.abs(go)))
            lines.append(f"| {case} | | plant responses of the two trees differ by {100 * rel:.2g} % at most | | | |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
