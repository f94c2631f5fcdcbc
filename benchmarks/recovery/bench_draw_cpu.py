"""CPU seconds of recovery draws under two source trees, the same draws run alternately.

    python benchmarks/recovery/bench_draw_cpu.py --before /tmp/base/src --after src \\
        --module rec_modified_pi --seeds 0-19

Two persistent worker processes, one per source tree (``PYTHONPATH`` of the package), one BLAS
thread each, run the draws in turn (seed 0 before, seed 0 after, seed 1 before, ...), so load
from other jobs falls on both alike.  Per draw: CPU seconds of the worker
(``resource.getrusage``, steadier than wall time on a shared machine), wall seconds, the row
(recovered, error, reference error, cost ratio).  Each worker first runs one draw that is not
counted, so the kernels' compilation or cache load is outside the figures.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import pathlib
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def _worker(src: str, module: str, jobs, results) -> None:
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[var] = "1"
    sys.path[:0] = [str(pathlib.Path(src).resolve()), str(HERE), str(HERE.parent)]
    import importlib
    import resource

    import run as runner

    mod = importlib.import_module(module)
    while (seed := jobs.get()) is not None:
        cpu0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            row = mod.case(seed, pathlib.Path(tmp), runner.draw_noise(seed))
        cpu1 = resource.getrusage(resource.RUSAGE_SELF)
        cpu = cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime
        results.put(
            (seed, cpu, time.perf_counter() - t0, row.recovered, row.error, row.reference_error, row.cost_ratio)
        )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, help="the package's source folder before (holds stageid/)")
    parser.add_argument("--after", required=True, help="the package's source folder after")
    parser.add_argument("--module", default="rec_modified_pi")
    parser.add_argument("--seeds", default="0-19")
    parser.add_argument("--warm-up-seed", type=int, default=1)
    args = parser.parse_args(argv)
    ctx = multiprocessing.get_context("spawn")
    workers = {}
    for name in ("before", "after"):
        jobs, results = ctx.Queue(), ctx.Queue()
        proc = ctx.Process(target=_worker, args=(getattr(args, name), args.module, jobs, results))
        proc.start()
        jobs.put(args.warm_up_seed)
        results.get()
        workers[name] = (proc, jobs, results)
    totals = {"before": [0.0, 0.0], "after": [0.0, 0.0]}
    print(
        "| seed | CPU s before | CPU s after | wall s before / after | cost ratio before / after | error before / after |"
    )
    print("|---|---|---|---|---|---|")
    for seed in _seeds(args.seeds):
        rows = {}
        for name, (_, jobs, results) in workers.items():
            jobs.put(seed)
            rows[name] = results.get()
            totals[name][0] += rows[name][1]
            totals[name][1] += rows[name][2]
        b, a = rows["before"], rows["after"]
        ok = "" if a[3] and b[3] else f" (recovered {b[3]} / {a[3]})"
        print(
            f"| {seed} | {b[1]:.2f} | {a[1]:.2f} | {b[2]:.1f} / {a[2]:.1f} | {b[6]:.6f} / {a[6]:.6f} | "
            f"{b[4]:.4g} / {a[4]:.4g}{ok} |",
            flush=True,
        )
    for _, jobs, _ in workers.values():
        jobs.put(None)
    for proc, _, _ in workers.values():
        proc.join()
    print(
        f"total CPU s before {totals['before'][0]:.1f}, after {totals['after'][0]:.1f}; "
        f"wall s before {totals['before'][1]:.1f}, after {totals['after'][1]:.1f}"
    )


if __name__ == "__main__":
    main()
