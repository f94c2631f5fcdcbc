"""Mutation testing of the estimators' and tools' core modules with cosmic-ray (``make mutation``).

Not part of ``make test``.  Each group mutates a few modules in place, one mutant at a time,
and runs the tests that cover them (``pytest -x``: a mutant is killed at its first failing
test).  Results go to ``$MUTATION_DIR`` (default ``.venv/mutation``), one cosmic-ray session per
group, so an interrupted run resumes where it stopped.

    python tests/mutation/run.py [GROUP ...] [--budget SECONDS] [--seed N] [--report]

Mutants run in a random order fixed by ``--seed`` (a permutation of the whole group, the same
on every resume), so a run cut short by its budget has tested a uniform random sample of the
group and its score is an unbiased estimate of the group's score.  ``--budget`` bounds the wall
time of each group; on expiry the run is stopped, the mutated module is restored from git, and
the finished mutants are reported (the rest stay pending for the next run).  The modules must have no uncommitted changes (they are restored with
``git checkout``).  See tests/MUTATION.md for the last recorded run.
"""

from __future__ import annotations

import argparse
import ast
import io
import json
import math
import os
import random
import signal
import sqlite3
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: group -> (modules mutated, tests run against each mutant, fastest first)
GROUPS: dict[str, tuple[list[str], list[str]]] = {
    "hysteresis-inverse": (
        ["src/stageid/hysteresis/inverse/__init__.py"],
        ["tests/test_hysteresis_inverse.py"],
    ),
    "hysteresis-identification": (
        ["src/stageid/hysteresis/inverse/closed_form.py", "src/stageid/hysteresis/identify/pi.py"],
        [
            "tests/test_hysteresis_inverse.py",  # pi_inverse / forward_state of closed_form.py
            "tests/test_hysteresis_identification.py",
            "tests/test_hysteresis_search.py",
            "tests/test_contract_estimators.py",  # PIIdentifier's frozen result and parameter rules
        ],
    ),
    "subspace-weighting": (
        ["src/stageid/subspace/realisation/weighting.py"],
        ["tests/test_subspace_output_weighting.py", "tests/test_subspace_estimator.py"],
    ),
    "subspace-result": (
        ["src/stageid/subspace/result.py"],
        ["tests/test_subspace_estimator.py", "tests/test_subspace_output_weighting.py"],
    ),
    "subspace-realization": (
        ["src/stageid/subspace/realisation/era.py"],
        ["tests/test_subspace_realization.py", "tests/test_subspace_estimator.py"],
    ),
    "subspace-map": (
        ["src/stageid/subspace/map/posterior.py", "src/stageid/subspace/statistics/hankel_toeplitz.py"],
        ["tests/test_subspace_map.py", "tests/test_subspace_hankel_toeplitz.py", "tests/test_subspace_estimator.py"],
    ),
    "closedloop-reduction": (
        ["src/stageid/closedloop/reduction.py", "src/stageid/closedloop/plant_reduction.py"],
        ["tests/test_closedloop_estimator.py", "tests/test_closedloop_deduction.py"],
    ),
    "closedloop-cancellation": (
        [
            "src/stageid/closedloop/cancellation.py",
            "src/stageid/closedloop/deduction.py",
            "src/stageid/closedloop/controller.py",
        ],
        [
            "tests/test_closedloop_cancellation_pairs.py",  # cancel_pairs against recomputed distances
            "tests/test_closedloop_deduction.py",
            "tests/test_closedloop_estimator.py",
        ],
    ),
    "frf": (
        ["src/stageid/frf/welch.py", "src/stageid/frf/periodic.py", "src/stageid/frf/lpm.py"],
        ["tests/test_frf_welch_overlap.py", "tests/test_frf_estimates.py"],
    ),
    "frd-fit": (
        ["src/stageid/frf/identification.py", "src/stageid/frf/fit_uncertainty.py"],
        ["tests/test_frf_identify.py", "tests/test_uncertainty_frd.py", "tests/test_frf_cli.py"],
    ),
    "export": (
        ["src/stageid/export/c_lti.py", "src/stageid/export/c_writer.py"],
        [
            "tests/test_export_lti_forms.py",
            # the LTI cases of the C tests (the hysteresis and compensator ones take minutes)
            "tests/test_export_c.py::test_statespace_matches_simulate",
            "tests/test_export_c.py::test_transfer_matrix_matches_simulate",
            "tests/test_export_c.py::test_static_gain_and_delay_only",
            "tests/test_export_c.py::test_continuous_models_discretised_on_the_way",
            "tests/test_export_c.py::test_constants_round_trip_exactly",
            "tests/test_export_c.py::test_hysteresis_forward_matches_simulate",  # c_writer's arrays
        ],
    ),
    "batch": (
        ["src/stageid/batch/runner.py", "src/stageid/batch/state.py"],
        ["tests/test_batch_runner.py", "tests/test_batch_jobs.py", "tests/test_batch.py"],
    ),
    "validation": (
        [
            "src/stageid/validation/residuals.py",
            "src/stageid/validation/correlation_tests.py",
            "src/stageid/validation/metrics.py",
        ],
        [
            "tests/test_validation_residual_statistics.py",
            "tests/test_validation_residuals.py",
            "tests/test_cli_validate.py",
        ],
    ),
    "disturbance-modes": (
        ["src/stageid/hysteresis/stage/disturbance_modes.py"],
        [
            "tests/test_stage_disturbance_modes.py",
            "tests/test_stage_evidence.py",
            "tests/test_killed_disturbance_modes.py",
        ],
    ),
    "creep": (
        ["src/stageid/hysteresis/models/creep.py"],
        ["tests/test_hysteresis_creep.py"],
    ),
    "preisach": (
        ["src/stageid/hysteresis/models/preisach.py", "src/stageid/hysteresis/identify/preisach.py"],
        ["tests/test_hysteresis_preisach.py", "tests/test_stage_preisach.py"],
    ),
    "stage": (
        ["src/stageid/hysteresis/stage/__init__.py", "src/stageid/hysteresis/stage/identification.py"],
        ["tests/test_hysteresis_stage.py", "tests/test_stage_dynamics_filter.py", "tests/test_stage_validation.py"],
    ),
}

#: operators whose mutants only raise TypeError on floats and arrays (bitwise replacements,
#: `~x`, `not x` for a unary minus): trivially killed, they would only inflate the score
EXCLUDED_OPERATORS = [
    r"core/ReplaceBinaryOperator_.*_(BitOr|BitAnd|BitXor|LShift|RShift)$",
    r"core/ReplaceUnaryOperator_.*_(Invert|Not)$",
]


def group_tests(group: str) -> list[str]:
    """The group's tests, then its ``tests/test_killed_<group>.py`` (the tests written to kill
    its survivors, tests/MUTATION.md) when there is one."""
    killed = f"tests/test_killed_{group.replace('-', '_')}.py"
    return GROUPS[group][1] + ([killed] if (ROOT / killed).exists() else [])


def _config(group: str, out: Path) -> Path:
    modules, tests = GROUPS[group][0], group_tests(group)
    cmd = f"{sys.executable} -m pytest -x -q -p no:cacheprovider " + " ".join(tests)
    text = "\n".join(
        [
            "[cosmic-ray]",
            f"module-path = {json.dumps(modules)}",
            "timeout = 300.0",
            "excluded-modules = []",
            f"test-command = {json.dumps(cmd)}",
            "",
            "[cosmic-ray.distributor]",
            'name = "local"',
            "",
            "[cosmic-ray.filters.operators-filter]",
            f"exclude-operators = {json.dumps(EXCLUDED_OPERATORS)}",
            "",
        ]
    )
    path = out / f"{group}.toml"
    path.write_text(text)
    return path


def _annotation_spans(path: Path) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """(start, end) positions of every annotation, when the module never evaluates them."""
    tree = ast.parse(path.read_text())
    future = any(
        isinstance(n, ast.ImportFrom) and n.module == "__future__" and any(a.name == "annotations" for a in n.names)
        for n in tree.body
    )
    if not future:
        return []
    spans = []
    for node in ast.walk(tree):
        anns = []
        if isinstance(node, ast.arg | ast.AnnAssign) and node.annotation is not None:
            anns.append(node.annotation)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.returns is not None:
            anns.append(node.returns)
        spans += [((a.lineno, a.col_offset), (a.end_lineno, a.end_col_offset)) for a in anns]
    return spans


def _skip_annotation_mutants(session: Path) -> None:
    """Mark mutants inside annotations skipped: with ``from __future__ import annotations`` they
    are never evaluated, so every such mutant is equivalent and would only count as a survivor."""
    with sqlite3.connect(session) as db:
        specs = db.execute(
            "SELECT s.job_id, s.module_path, s.start_pos_row, s.start_pos_col FROM mutation_specs s "
            "LEFT JOIN work_results r ON r.job_id = s.job_id WHERE r.job_id IS NULL"
        ).fetchall()
        spans: dict[str, list] = {}
        for job, module, row, col in specs:
            if module not in spans:
                spans[module] = _annotation_spans(ROOT / module)
            if any(a <= (row, col) < b for a, b in spans[module]):
                db.execute(
                    "INSERT INTO work_results (worker_outcome, output, test_outcome, diff, job_id) "
                    "VALUES ('SKIPPED', 'Annotation (never evaluated)', NULL, NULL, ?)",
                    (job,),
                )


def _counts(session: Path) -> dict[str, int]:
    """Finished mutants by outcome (``skipped``: removed by the operator filter)."""
    with sqlite3.connect(session) as db:
        rows = db.execute("SELECT worker_outcome, test_outcome, COUNT(*) FROM work_results GROUP BY 1, 2").fetchall()
        total = db.execute("SELECT COUNT(*) FROM work_items").fetchone()[0]
    out = {"total": total}
    for worker, test, n in rows:
        key = "skipped" if worker == "SKIPPED" else "timeout" if worker == "TIMEOUT" else str(test).lower()
        out[key] = out.get(key, 0) + n
    return out


def sample_order(job_ids: list[str], seed: int) -> list[str]:
    """The group's mutants in the order they are run: a permutation fixed by ``seed`` alone, so
    every prefix is a uniform random sample and a resumed run continues the same sample."""
    order = sorted(job_ids)
    random.Random(seed).shuffle(order)
    return order


def execute_in_order(session: Path, cfg: Path, seed: int) -> None:
    """``cosmic-ray exec`` with the pending mutants taken in ``sample_order`` (cosmic-ray's own
    order is an unseeded SQL ``random()``), one line per mutant on stdout."""
    from cosmic_ray.config import load_config
    from cosmic_ray.mutating import mutate_and_test
    from cosmic_ray.work_db import WorkDB, use_db

    config = load_config(cfg)
    with use_db(session, WorkDB.Mode.open) as db:
        pending = {item.job_id: item for item in db.pending_work_items}
        order = sample_order([item.job_id for item in db.work_items], seed)
        for job_id in order:
            if job_id not in pending:
                continue
            t0 = time.monotonic()
            result = mutate_and_test(pending[job_id].mutations, config.test_command, config.timeout)
            db.set_result(job_id, result)
            m = pending[job_id].mutations[0]
            outcome = result.test_outcome.value if result.test_outcome else result.worker_outcome.value
            print(
                f"{outcome:>9} {time.monotonic() - t0:6.1f} s  {m.module_path}:{m.start_pos[0]} {m.operator_name}",
                flush=True,
            )


def recheck(group: str, session: Path, jobs: list[str] | None, tests: list[str] | None) -> None:
    """Re-run recorded survivors (or ``jobs``) against the current tests, without touching the
    working tree: each mutant is applied to a copy of the committed ``src`` put first on
    ``PYTHONPATH``, so this can run while a mutation run has a mutant applied in place.
    Prints the outcome and the first failing test of each mutant."""
    from cosmic_ray.mutating import apply_mutation
    from cosmic_ray.plugins import get_operator
    from cosmic_ray.work_db import WorkDB, use_db

    tests = tests or group_tests(group)
    with use_db(session, WorkDB.Mode.open) as db:
        items = [
            (item, result)
            for item, result in db.completed_work_items
            if (jobs and item.job_id in jobs)
            or (not jobs and result.test_outcome is not None and result.test_outcome.value == "survived")
        ]
    with tempfile.TemporaryDirectory(prefix="mutation-recheck-") as tmp:
        archive = subprocess.run(
            ["git", "archive", "--format=tar", "HEAD", "src"], cwd=ROOT, capture_output=True, check=True
        )
        with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
            tar.extractall(tmp, filter="data")
        env = dict(os.environ, PYTHONPATH=str(Path(tmp) / "src"), PYTHONDONTWRITEBYTECODE="1", OMP_NUM_THREADS="1")
        for item, _ in items:
            m = item.mutations[0]
            path = Path(tmp) / m.module_path
            original = path.read_text()
            try:
                apply_mutation(path, get_operator(m.operator_name)(**(m.operator_args or {})), m.occurrence)
                cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
                run = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
            finally:
                path.write_text(original)
            failed = [ln.split()[1] for ln in run.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))]
            outcome = "killed" if run.returncode else "survived"
            print(f"{item.job_id} {m.module_path}:{m.start_pos[0]} {m.operator_name} -> {outcome} {' '.join(failed)}")


def run_group(group: str, out: Path, budget: float, seed: int = 0) -> dict[str, int]:
    modules, _ = GROUPS[group]
    dirty = subprocess.run(["git", "diff", "--quiet", "--", *modules], cwd=ROOT).returncode
    if dirty:
        raise SystemExit(f"{group}: {modules} have uncommitted changes; commit them first (they are restored by git).")
    cfg, session = _config(group, out), out / f"{group}.sqlite"
    cr = Path(sys.executable).parent
    if not session.exists():
        subprocess.run([cr / "cosmic-ray", "init", cfg, session], cwd=ROOT, check=True)
        subprocess.run([cr / "cr-filter-operators", session, cfg], cwd=ROOT, check=True)
        _skip_annotation_mutants(session)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    worker = [sys.executable, __file__, group, "--exec-session", str(session), "--seed", str(seed)]
    proc = subprocess.Popen(worker, cwd=ROOT, env=env, start_new_session=True)
    try:
        proc.wait(timeout=budget)
    except subprocess.TimeoutExpired:
        # cosmic-ray starts each test run in a session of its own: stop it by its id as well,
        # or an orphaned pytest of the last mutant keeps running after the budget
        tests = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
        os.killpg(proc.pid, signal.SIGTERM)  # the session this run started, nothing else
        for pid in tests:
            try:
                os.killpg(int(pid), signal.SIGTERM)
            except ProcessLookupError:
                pass
        proc.wait()
    finally:
        subprocess.run(["git", "checkout", "--", *modules], cwd=ROOT, check=True)  # no mutant left behind
    return _counts(session)


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson interval of a score k/n estimated from a random sample of n mutants."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(centre - half, 0.0), min(centre + half, 1.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("groups", nargs="*", default=list(GROUPS))
    ap.add_argument("--budget", type=float, default=3600.0, help="wall seconds per group")
    ap.add_argument("--seed", type=int, default=0, help="seed of the order the mutants are sampled in")
    ap.add_argument("--report", action="store_true", help="only print the survivors of finished sessions")
    ap.add_argument("--recheck", action="store_true", help="re-run the survivors against the current tests")
    ap.add_argument("--jobs", nargs="*", help="with --recheck: these job ids instead of the survivors")
    ap.add_argument("--tests", nargs="*", help="with --recheck: these tests instead of the group's")
    ap.add_argument("--exec-session", type=Path, help=argparse.SUPPRESS)  # the budgeted worker run_group starts
    args = ap.parse_args()
    if args.exec_session:
        execute_in_order(args.exec_session, args.exec_session.with_suffix(".toml"), args.seed)
        return
    out = Path(os.environ.get("MUTATION_DIR", ROOT / ".venv" / "mutation"))
    out.mkdir(parents=True, exist_ok=True)
    cr = Path(sys.executable).parent
    for group in args.groups:
        if args.recheck:
            recheck(group, out / f"{group}.sqlite", args.jobs, args.tests)
            continue
        if not args.report:
            t0 = time.monotonic()
            c = run_group(group, out, args.budget, args.seed)
            run = sum(v for k, v in c.items() if k not in ("total", "skipped"))
            killed = c.get("killed", 0) + c.get("timeout", 0)
            pending = c["total"] - run - c.get("skipped", 0)
            scored = run - c.get("incompetent", 0)
            lo, hi = wilson_interval(killed, scored)
            print(
                f"{group}: {run} of {run + pending} mutants run in {time.monotonic() - t0:.0f} s "
                f"({c.get('skipped', 0)} filtered, {pending} pending, seed {args.seed}), killed {killed} "
                f"(timeouts {c.get('timeout', 0)}), survived {c.get('survived', 0)}, incompetent "
                f"{c.get('incompetent', 0)}, score {killed / max(scored, 1):.1%} (95 % interval {lo:.0%}-{hi:.0%})",
                flush=True,
            )
        subprocess.run([cr / "cr-report", "--surviving-only", "--show-diff", out / f"{group}.sqlite"], cwd=ROOT)


if __name__ == "__main__":
    main()
