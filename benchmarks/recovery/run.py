"""Run the randomised recovery benchmark: every ``rec_*.py`` beside this file, ``--draws`` seeds each.

    python benchmarks/recovery/run.py                       # all estimators, 20 draws, 2 workers
    python benchmarks/recovery/run.py --estimators pem,frd --draws 5 --noise 0.005 --report-only

Each draw runs in a fresh temporary folder in one of ``--jobs`` worker processes, with a noise
level drawn from the seed in 0-2 % (or ``--noise``), longest first by the last run's draw tables
(``--timings``, default ``--out`` or ``benchmarks/RESULTS-recovery.md``; :mod:`draw_order`). One
progress line per draw; when the time budget is spent the draws not yet started are dropped and
the table says how many. The table recovery rate over all draws and over draws at noise <= 1 %, median and worst error, median
reference error, cost ratio median and 95th percentile, failures, seconds) is printed and written as the section "Summary" of ``--out``, other sections left as they are.

Exit status 1 when a target is missed (unless ``--report-only``): recovery >= 95 % at noise
<= 1 %; for estimators that declare them (``TARGETS`` in the module, the FRD fit by default), the
median error within a factor of the median reference error and the cost ratio at most a bound on
a share of the draws.
"""

from __future__ import annotations

import os

# one BLAS thread per worker: two workers on two cores, not two times a pool each
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import importlib  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import pathlib  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait  # noqa: E402

import numpy as np  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
# rec modules import ``common`` by plain name or relatively as ``recovery.common``
for _p in (HERE, HERE.parent):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from common import draw_noise  # noqa: E402 - the runner's, in __all__
from draw_order import longest_first, previous_seconds  # noqa: E402

LOW_NOISE = 0.01  # the recovery target holds at noise <= 1 %
RECOVERY_TARGET = 0.95
# The FRD fit's targets: median max error within 1.3x of the reference fit's, cost ratio <= 1.01
# on 95 % of the draws.
FRD_TARGETS = {"error_vs_reference": 1.3, "cost_ratio": 1.01, "cost_ratio_share": 0.95}

__all__ = [
    "Outcome",
    "Summary",
    "discover",
    "draw_noise",
    "run_one",
    "run_group",
    "group_tasks",
    "run_all",
    "summarise",
    "missed_targets",
    "format_table",
    "format_draws",
    "write_summary",
    "main",
]


@dataclasses.dataclass
class Outcome:
    """One draw as the runner saw it: the module's Row fields plus where and how long."""

    estimator: str
    module: str
    seed: int
    noise: float
    recovered: bool
    error: float
    unit: str
    reference_error: float
    cost_ratio: float
    failed: str
    detail: str
    seconds: float


@dataclasses.dataclass
class Summary:
    estimator: str
    module: str
    draws: int
    recovered: int
    low_noise_draws: int
    low_noise_recovered: int
    unit: str
    median_error: float
    worst_error: float
    median_reference_error: float
    cost_ratio_median: float
    cost_ratio_p95: float
    cost_ratio_share: float  # share of draws with a cost ratio within the module's bound
    failures: list[str]
    seconds: float
    targets: dict
    dropped: int = 0


def discover(names: list[str] | None = None) -> dict[str, str]:
    """``{module: ESTIMATOR label}`` of every ``rec_*.py`` here (or only ``names``, given as
    ``pem`` or ``rec_pem``); KeyError naming the unknown ones."""
    found = {p.stem: p for p in sorted(HERE.glob("rec_*.py"))}
    if names:
        wanted = [n if n.startswith("rec_") else f"rec_{n}" for n in names]
        unknown = [n for n in wanted if n not in found]
        if unknown:
            raise KeyError(f"no recovery module {', '.join(unknown)}; found {', '.join(found) or 'none'}")
        found = {n: found[n] for n in wanted}
    return {name: _load(name).ESTIMATOR for name in found}


def _load(module: str):
    return importlib.import_module(f"recovery.{module}")


def _on_alarm(signum, frame):  # noqa: ARG001
    raise TimeoutError("draw stopped by the per-draw time limit")


def run_one(
    module: str, seed: int, noise: float, case_timeout: float = 0.0, workdir: pathlib.Path | None = None
) -> Outcome:
    """One draw of ``module`` in a fresh temporary folder (or in ``workdir``, shared with the other
    cases of its draw); a case that raises or overruns ``case_timeout`` seconds is a failed draw
    with its message."""
    mod = _load(module)
    t0 = time.perf_counter()
    use_alarm = case_timeout > 0 and hasattr(signal, "SIGALRM")
    if use_alarm:
        old = signal.signal(signal.SIGALRM, _on_alarm)
        signal.setitimer(signal.ITIMER_REAL, case_timeout)
    try:
        if workdir is not None:
            row = mod.case(seed, workdir, noise)
        else:
            with tempfile.TemporaryDirectory(prefix=f"{module}-{seed}-") as tmp:
                row = mod.case(seed, pathlib.Path(tmp), noise)
        fields = {k: getattr(row, k) for k in ("recovered", "error", "unit", "reference_error", "cost_ratio")}
        fields.update(failed=str(getattr(row, "failed", "") or ""), detail=str(getattr(row, "detail", "") or ""))
    except Exception as exc:  # a crashing case is a failed draw, reported with its message
        msg = str(exc).strip().splitlines()
        fields = dict(
            recovered=False, error=math.nan, unit="", reference_error=math.nan, cost_ratio=math.nan,
            failed=f"{type(exc).__name__}: {msg[-1] if msg else ''}", detail="",
        )  # fmt: skip
    finally:
        if use_alarm:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
    return Outcome(
        estimator=mod.ESTIMATOR, module=module, seed=seed, noise=noise, seconds=time.perf_counter() - t0,
        recovered=bool(fields["recovered"]) and not fields["failed"], error=float(fields["error"]),
        unit=fields["unit"], reference_error=float(fields["reference_error"]),
        cost_ratio=float(fields["cost_ratio"]), failed=fields["failed"], detail=fields["detail"],
    )  # fmt: skip


def run_group(modules: tuple[str, ...], seed: int, noise: float, case_timeout: float = 0.0) -> list[Outcome]:
    """The draws of ``modules`` at one seed that share their fit (``SHARED_DRAW``), in one folder and
    in order: the first case runs the command, the others score what it left there, so its seconds
    are counted in the first case's row."""
    if len(modules) == 1:
        return [run_one(modules[0], seed, noise, case_timeout)]
    with tempfile.TemporaryDirectory(prefix=f"{'+'.join(modules)}-{seed}-") as tmp:
        return [run_one(m, seed, noise, case_timeout, workdir=pathlib.Path(tmp)) for m in modules]


def group_tasks(modules: list[str], seeds: list[int], noise: float | None) -> list[tuple]:
    """``(modules, seed, noise)`` per seed and draw: the modules that declare the same
    ``SHARED_DRAW`` run together, the others alone."""
    groups: dict[str, list[str]] = {}
    for m in modules:
        groups.setdefault(getattr(_load(m), "SHARED_DRAW", m), []).append(m)
    return [(tuple(g), s, draw_noise(s) if noise is None else float(noise)) for s in seeds for g in groups.values()]


def _progress(o: Outcome, done: int, total: int, stream) -> None:
    state = "ok  " if o.recovered else ("FAIL" if o.failed else "miss")
    tail = o.failed or o.detail
    print(
        f"[{done:>4}/{total}] {state} {o.estimator:<16} seed {o.seed:>3} noise {100 * o.noise:4.2f}% "
        f"error {o.error:9.4g} ref {o.reference_error:9.4g} cost x{o.cost_ratio:7.4f} {o.seconds:6.1f}s  {tail}",
        file=stream,
        flush=True,
    )


def run_all(
    modules: list[str],
    seeds: list[int],
    noise: float | None = None,
    jobs: int = 2,
    budget: float = 0.0,
    case_timeout: float = 0.0,
    stream=sys.stdout,
    seconds: dict[tuple[str, int], float] | None = None,
) -> tuple[list[Outcome], dict[str, int]]:
    """Every (module, seed) draw, longest first by ``seconds`` (:func:`longest_first`; in the given
    order without); returns the outcomes in module then seed order and, per module, how many
    draws the time ``budget`` (seconds, 0 = none) dropped before they started."""
    tasks = group_tasks(modules, seeds, noise)
    if seconds is not None:
        tasks = longest_first(tasks, {m: _load(m).ESTIMATOR for m in modules}, seconds)
    out: list[Outcome] = []
    total = len(modules) * len(seeds)
    t0 = time.perf_counter()
    over = lambda: budget > 0 and time.perf_counter() - t0 > budget  # noqa: E731
    if jobs <= 1:
        for task in tasks:
            if over():
                break
            for o in run_group(*task, case_timeout):
                out.append(o)
                _progress(o, len(out), total, stream)
    else:
        ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            pending, queue = set(), list(tasks)
            while queue or pending:
                while queue and len(pending) < jobs and not over():
                    pending.add(pool.submit(run_group, *queue.pop(0), case_timeout))
                if not pending:
                    break
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for o in (o for f in finished for o in f.result()):
                    out.append(o)
                    _progress(o, len(out), total, stream)
    ran = {(o.module, o.seed) for o in out}
    dropped = {m: sum((m, s) not in ran for s in seeds) for m in modules}
    out.sort(key=lambda o: (modules.index(o.module), o.seed))
    return out, dropped


def _median(values: list[float]) -> float:
    v = [x for x in values if math.isfinite(x)]
    return float(np.median(v)) if v else math.nan


def summarise(outcomes: list[Outcome], dropped: dict[str, int] | None = None) -> list[Summary]:
    """One Summary per module, in the order the modules first appear."""
    rows = []
    for module in dict.fromkeys(o.module for o in outcomes):
        group = [o for o in outcomes if o.module == module]
        targets = _targets(module)
        low = [o for o in group if o.noise <= LOW_NOISE]
        errors = [o.error for o in group if not o.failed]
        ratios = [o.cost_ratio for o in group if math.isfinite(o.cost_ratio)]
        bound = targets.get("cost_ratio", math.inf)
        rows.append(
            Summary(
                estimator=group[0].estimator, module=module, draws=len(group),
                recovered=sum(o.recovered for o in group), low_noise_draws=len(low),
                low_noise_recovered=sum(o.recovered for o in low),
                unit=next((o.unit for o in group if o.unit and not o.failed), ""),
                median_error=_median(errors), worst_error=max(errors, default=math.nan, key=_nan_low),
                median_reference_error=_median([o.reference_error for o in group]),
                cost_ratio_median=_median(ratios),
                cost_ratio_p95=float(np.percentile(ratios, 95)) if ratios else math.nan,
                cost_ratio_share=(sum(r <= bound for r in ratios) / len(group)) if group else math.nan,
                failures=[f"seed {o.seed}: {o.failed}" for o in group if o.failed],
                seconds=sum(o.seconds for o in group), targets=targets,
                dropped=(dropped or {}).get(module, 0),
            )
        )  # fmt: skip
    return rows


def _nan_low(x: float) -> float:
    return x if math.isfinite(x) else -math.inf


def _targets(module: str) -> dict:
    declared = getattr(_load(module), "TARGETS", None)
    if declared is not None:
        return dict(declared)
    return dict(FRD_TARGETS) if module == "rec_frd" else {}


def missed_targets(rows: list[Summary]) -> list[str]:
    """One line per target a summary row misses (empty when all are met)."""
    missed = []
    for r in rows:
        if r.low_noise_draws and r.low_noise_recovered / r.low_noise_draws < RECOVERY_TARGET:
            missed.append(
                f"{r.estimator}: recovery at noise <= 1 % is {r.low_noise_recovered}/{r.low_noise_draws}; "
                f"target >= {RECOVERY_TARGET:.0%}"
            )
        factor = r.targets.get("error_vs_reference")
        if factor and not r.median_error <= factor * r.median_reference_error:
            missed.append(
                f"{r.estimator}: median error {r.median_error:.4g} vs reference {r.median_reference_error:.4g}; "
                f"target <= {factor}x"
            )
        share = r.targets.get("cost_ratio_share")
        if share and not r.cost_ratio_share >= share:
            missed.append(
                f"{r.estimator}: cost ratio <= {r.targets['cost_ratio']} on {r.cost_ratio_share:.0%} of draws; "
                f"target >= {share:.0%}"
            )
        if r.dropped:
            missed.append(f"{r.estimator}: {r.dropped} draws not run (time budget spent)")
    return missed


def _pct(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / n:.0f} %)" if n else "-"


def _g(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "-"


def format_table(rows: list[Summary]) -> str:
    """The summary as a Markdown table, then the failures' messages."""
    head = (
        "| estimator | draws | recovered | recovered, noise <= 1 % | median error | worst error | "
        "median reference error | cost ratio median | cost ratio p95 | failures | seconds |"
    )
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        unit = f" ({r.unit})" if r.unit else ""
        lines.append(
            f"| {r.estimator} | {r.draws}{f' (+{r.dropped} not run)' if r.dropped else ''} "
            f"| {_pct(r.recovered, r.draws)} | {_pct(r.low_noise_recovered, r.low_noise_draws)} "
            f"| {_g(r.median_error)}{unit} | {_g(r.worst_error)} | {_g(r.median_reference_error)} "
            f"| {_g(r.cost_ratio_median)} | {_g(r.cost_ratio_p95)} | {len(r.failures)} | {r.seconds:.0f} |"
        )
    notes = [f"- {r.estimator}, {f}" for r in rows for f in r.failures]
    if notes:
        lines += ["", "Failures (the command's message):", "", *notes]
    return "\n".join(lines)


def format_draws(outcomes: list[Outcome]) -> str:
    """Every draw of one estimator as a Markdown table (seed order)."""
    lines = [
        "| seed | noise % | recovered | error | reference error | cost ratio | seconds | detail or failure |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for o in sorted(outcomes, key=lambda o: o.seed):
        state = "yes" if o.recovered else ("failed" if o.failed else "no")
        lines.append(
            f"| {o.seed} | {100 * o.noise:.2f} | {state} | {_g(o.error)} | {_g(o.reference_error)} "
            f"| {_g(o.cost_ratio)} | {o.seconds:.1f} | {(o.failed or o.detail).replace('|', '/')} |"
        )
    return "\n".join(lines)


def write_summary(path: pathlib.Path, text: str, heading: str = "## Summary") -> None:
    """Put ``text`` under ``heading`` in ``path``, replacing that section only."""
    old = path.read_text() if path.exists() else "# Randomised recovery benchmark\n"
    lines = old.splitlines()
    if heading in lines:
        start = lines.index(heading)
        end = next((k for k in range(start + 1, len(lines)) if lines[k].startswith("## ")), len(lines))
        lines[start:end] = [heading, "", *text.splitlines(), ""]
    else:
        lines += ["", heading, "", *text.splitlines()]
    path.write_text("\n".join(lines).rstrip("\n") + "\n")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draws", type=int, default=20, help="seeds per estimator (default 20)")
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--noise", type=float, default=None, help="fixed noise level (fraction; default: drawn 0-0.02)")
    p.add_argument("--estimators", default="", help="comma list of modules (pem or rec_pem); default all")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--budget", type=float, default=570.0, help="seconds after which no draw starts (0: none)")
    p.add_argument("--case-timeout", type=float, default=120.0, help="seconds one draw may take (0: none)")
    p.add_argument("--out", type=pathlib.Path, default=None, help="Markdown file whose 'Summary' section is rewritten")
    p.add_argument("--timings", type=pathlib.Path, default=None, help="draw tables ordering the draws (draw_order)")
    p.add_argument("--report-only", action="store_true", help="exit 0 even when a target is missed")
    p.add_argument(
        "--draw-tables",
        action="store_true",
        help="also write each estimator's draws under '## <label>: draws' in --out",
    )
    a = p.parse_args(argv)
    names = [n.strip() for n in a.estimators.split(",") if n.strip()]
    try:
        modules = list(discover(names or None))
    except KeyError as exc:
        print(exc.args[0], file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    seeds = list(range(a.first_seed, a.first_seed + a.draws))
    seconds = previous_seconds(a.timings or a.out or HERE.parent / "RESULTS-recovery.md")
    outcomes, dropped = run_all(modules, seeds, a.noise, a.jobs, a.budget, a.case_timeout, seconds=seconds)
    rows = summarise(outcomes, dropped)
    noise = "drawn per seed in 0-2 %" if a.noise is None else f"{100 * a.noise:g} %"
    text = (
        f"{a.draws} draws per estimator (seeds {seeds[0]}-{seeds[-1]}), noise {noise}, {a.jobs} workers, "
        f"{time.perf_counter() - t0:.0f} s wall.\n\n{format_table(rows)}"
    )
    print("\n" + text)
    missed = missed_targets(rows)
    for line in missed:
        print(f"target missed: {line}", file=sys.stderr)
    if a.out is not None:
        write_summary(a.out, text)
        for label in dict.fromkeys(o.estimator for o in outcomes) if a.draw_tables else ():
            mine = [o for o in outcomes if o.estimator == label]
            write_summary(a.out, format_draws(mine), heading=f"## {label}: draws")
    return 1 if missed and not a.report_only else 0


if __name__ == "__main__":
    sys.exit(main())
