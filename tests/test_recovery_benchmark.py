"""A small draw of the randomised recovery benchmark (benchmarks/recovery): every estimator's
case module found there runs two seeded random stages of its own class at 0.5 % noise through
the command line, and each must be recovered by its module's stated criterion; the runner's
table and target check are tested on made-up outcomes."""

from __future__ import annotations

import importlib.util
import math
import pathlib
import sys

import pytest

RECOVERY = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "recovery"


def _runner():
    spec = importlib.util.spec_from_file_location("recovery_run", RECOVERY / "run.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["recovery_run"] = mod
    spec.loader.exec_module(mod)
    return mod


run = _runner()
import draw_order  # noqa: E402 - beside run.py, on the path run.py sets

MODULES = sorted(p.stem for p in RECOVERY.glob("rec_*.py"))
# Estimators that miss the benchmark's target (benchmarks/RESULTS-recovery.md gives the draws and
# the causes). Strict: when one recovers its small draw, the mark fails and must go.
SHORT_OF_TARGET: dict[str, str] = {}
CASES = [
    pytest.param(m, marks=pytest.mark.xfail(strict=True, reason=SHORT_OF_TARGET[m])) if m in SHORT_OF_TARGET else m
    for m in MODULES
]
SEEDS = (0, 1)
NOISE = 0.005  # inside the benchmark's target range (noise <= 1 %)


def test_every_case_module_is_found():
    found = run.discover()
    assert set(found) == set(MODULES)
    assert all(isinstance(label, str) and label for label in found.values())


@pytest.mark.study
@pytest.mark.slow
@pytest.mark.parametrize("module", CASES)
def test_small_draw_is_recovered(module):
    outcomes, dropped = run.run_all([module], list(SEEDS), NOISE, jobs=1, stream=sys.stderr)
    assert not dropped[module]
    bad = [f"seed {o.seed}: {o.failed or o.detail} (error {o.error:.3g} {o.unit})" for o in outcomes if not o.recovered]
    assert not bad, f"{outcomes[0].estimator} not recovered: " + "; ".join(bad)


def _outcome(module, seed, noise, recovered, error, ref=math.nan, ratio=math.nan, failed=""):
    return run.Outcome(module, module, seed, noise, recovered, error, "%", ref, ratio, failed, "", 1.0)


def test_summary_counts_and_targets(monkeypatch):
    monkeypatch.setattr(run, "_targets", lambda module: {})
    # recovery counted over all draws and over the draws at noise <= 1 %; a failure is not recovered
    outs = [
        _outcome("rec_a", 0, 0.005, True, 1.0),
        _outcome("rec_a", 1, 0.015, False, 9.0),
        _outcome("rec_a", 2, 0.002, False, math.nan, failed="stageid: error: no"),
    ]
    (row,) = run.summarise(outs)
    assert (row.draws, row.recovered, row.low_noise_draws, row.low_noise_recovered) == (3, 1, 2, 1)
    assert row.median_error == 5.0 and row.worst_error == 9.0
    assert row.failures == ["seed 2: stageid: error: no"]
    missed = run.missed_targets([row])
    assert len(missed) == 1 and "1/2" in missed[0]
    table = run.format_table([row])
    assert "| rec_a | 3 | 1/3 (33 %) | 1/2 (50 %) |" in table and "stageid: error: no" in table


def test_frd_targets_are_checked(monkeypatch):
    monkeypatch.setattr(run, "_targets", lambda module: dict(run.FRD_TARGETS))
    good = [_outcome("rec_f", s, 0.005, True, 1.2, ref=1.0, ratio=1.0 + s * 1e-4) for s in range(20)]
    assert run.missed_targets(run.summarise(good)) == []
    # median error 1.4x the reference's and 2 of 20 draws above the cost-ratio bound: both missed
    bad = [_outcome("rec_f", s, 0.005, True, 1.4, ref=1.0, ratio=1.05 if s < 2 else 1.0) for s in range(20)]
    missed = run.missed_targets(run.summarise(bad))
    assert len(missed) == 2 and "1.3x" in missed[0] and "90%" in missed[1]


def test_summary_section_replaced_in_place(tmp_path):
    out = tmp_path / "RESULTS.md"
    out.write_text("# R\n\n## Summary\n\nold\n\n## PEM\n\nkept\n")
    run.write_summary(out, "new table")
    assert out.read_text() == "# R\n\n## Summary\n\nnew table\n\n## PEM\n\nkept\n"
    fresh = tmp_path / "fresh.md"
    run.write_summary(fresh, "t")
    assert "## Summary\n\nt\n" in fresh.read_text()


def test_draw_seconds_read_back_from_the_draw_tables(tmp_path):
    out = tmp_path / "RESULTS.md"
    outs = [_outcome("rec_a", 0, 0.005, True, 1.0), _outcome("rec_a", 3, 0.005, False, 2.0, failed="x | y")]
    outs[1].seconds = 42.5
    run.write_summary(out, run.format_draws(outs), heading="## rec_a: draws")
    run.write_summary(out, "| 9 | 0.10 | yes | 1 | - | - | 7.0 | a table of another section |", heading="## Notes")
    assert draw_order.previous_seconds(out) == {("rec_a", 0): 1.0, ("rec_a", 3): 42.5}
    assert draw_order.previous_seconds(tmp_path / "absent.md") == {}


def test_draws_start_longest_first_and_come_back_in_order():
    labels = {"rec_a": "A", "rec_b": "B", "rec_new": "New"}
    seconds = {("A", 0): 5.0, ("A", 1): 50.0, ("B", 0): 20.0}
    tasks = [(m, s, 0.0) for s in (0, 1) for m in labels]
    order = draw_order.longest_first(tasks, labels, seconds)
    # never timed first (it may be the longest), then by the last run's seconds; B's seed 1 at B's median
    assert [t[:2] for t in order] == [
        ("rec_new", 0), ("rec_new", 1), ("rec_a", 1), ("rec_b", 0), ("rec_b", 1), ("rec_a", 0),
    ]  # fmt: skip


def test_run_all_returns_outcomes_in_module_and_seed_order(monkeypatch):
    started = []

    def fake_run_one(module, seed, noise, case_timeout=0.0):
        started.append((module, seed))
        return _outcome(module, seed, noise, True, 1.0)

    monkeypatch.setattr(run, "run_one", fake_run_one)
    monkeypatch.setattr(run, "_load", lambda m: type("M", (), {"ESTIMATOR": m.upper()}))
    seconds = {("REC_B", 1): 9.0, ("REC_A", 0): 3.0, ("REC_A", 1): 1.0, ("REC_B", 0): 2.0}
    outs, dropped = run.run_all(["rec_a", "rec_b"], [0, 1], 0.005, jobs=1, stream=sys.stderr, seconds=seconds)
    assert started == [("rec_b", 1), ("rec_a", 0), ("rec_b", 0), ("rec_a", 1)]
    assert [(o.module, o.seed) for o in outs] == [("rec_a", 0), ("rec_a", 1), ("rec_b", 0), ("rec_b", 1)]
    assert dropped == {"rec_a": 0, "rec_b": 0}


def _fake_modules(monkeypatch, shared: dict[str, str]):
    """Case modules rec_* whose ``SHARED_DRAW`` is ``shared[module]`` (absent: their own draw)."""

    def load(m):
        attrs = {"ESTIMATOR": m.upper()}
        if m in shared:
            attrs["SHARED_DRAW"] = shared[m]
        return type("M", (), attrs)

    monkeypatch.setattr(run, "_load", load)


def test_cases_that_share_a_draw_run_as_one_task_per_seed(monkeypatch):
    _fake_modules(monkeypatch, {"rec_pem": "loop", "rec_closedloop": "loop"})
    tasks = run.group_tasks(["rec_closedloop", "rec_frd", "rec_pem"], [0, 1], 0.005)
    assert [t[:2] for t in tasks] == [
        (("rec_closedloop", "rec_pem"), 0), (("rec_frd",), 0), (("rec_closedloop", "rec_pem"), 1), (("rec_frd",), 1),
    ]  # fmt: skip
    labels = {"rec_closedloop": "CL", "rec_pem": "PEM", "rec_frd": "FRD"}
    seconds = {("CL", 0): 1.0, ("PEM", 0): 30.0, ("FRD", 0): 20.0, ("CL", 1): 1.0, ("PEM", 1): 10.0, ("FRD", 1): 12.0}
    # a shared draw is as long as its cases together
    order = draw_order.longest_first(tasks, labels, seconds)
    assert [t[:2] for t in order] == [
        (("rec_closedloop", "rec_pem"), 0), (("rec_frd",), 0), (("rec_frd",), 1), (("rec_closedloop", "rec_pem"), 1),
    ]  # fmt: skip


def test_a_shared_draw_runs_its_cases_in_one_folder_and_reports_each(monkeypatch):
    _fake_modules(monkeypatch, {"rec_pem": "loop", "rec_closedloop": "loop"})
    folders = []

    def fake_run_one(module, seed, noise, case_timeout=0.0, workdir=None):
        folders.append(workdir)
        return _outcome(module, seed, noise, True, 1.0)

    monkeypatch.setattr(run, "run_one", fake_run_one)
    outs, dropped = run.run_all(["rec_closedloop", "rec_pem"], [0, 1], 0.005, jobs=1, stream=sys.stderr)
    assert [(o.module, o.seed) for o in outs] == [
        ("rec_closedloop", 0), ("rec_closedloop", 1), ("rec_pem", 0), ("rec_pem", 1),
    ]  # fmt: skip
    assert folders[0] is not None and folders[0] == folders[1] and folders[2] == folders[3] != folders[0]
    assert dropped == {"rec_closedloop": 0, "rec_pem": 0}


def test_the_loop_cases_fit_each_truth_once(monkeypatch, tmp_path):
    import loop_draws

    calls = []
    monkeypatch.setattr(loop_draws, "run_cli", lambda argv: calls.append(argv))
    first = loop_draws.draw_and_fit(3, tmp_path, 0.004)
    again = loop_draws.draw_and_fit(3, tmp_path, 0.004)
    assert len(calls) == 1 and again.detail == first.detail and again.unstable.tolist() == first.unstable.tolist()
    assert {"--closed-loop-output", "-o"} <= {str(a) for a in calls[0]}
    loop_draws.draw_and_fit(3, tmp_path, 0.008)  # another noise level is another draw
    assert len(calls) == 2
