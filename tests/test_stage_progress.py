"""A stage fit with ``--dynamics auto --creep auto`` reports its progress on stderr and prints a
short table of the held-out candidates (the best few and the chosen one), not one line each."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import cont2discrete

from conftest import run_main
from stageid.data.io import write_csv
from stageid.hysteresis import PIModel
from stageid.hysteresis.stage import StageModel
from stageid.hysteresis.stage.dynamics import transfer_to_statespace
from stageid.hysteresis.stage.identification import AUTO_CREEP, AUTO_ORDERS, SUMMARY_CANDIDATES, StageIdentifier
from stageid.signals import decaying_triangle

DT = 1e-4
N_CANDIDATES = len(AUTO_ORDERS) * len(AUTO_CREEP)


def _stage_record():
    wn = 2 * np.pi * 800.0
    b, a, _ = cont2discrete(([wn**2], [1.0, 2 * 0.05 * wn, wn**2]), DT, "zoh")
    b = np.ravel(b) * np.sum(a) / np.sum(np.ravel(b))
    true = StageModel(PIModel(r=[0.0, 2.5, 5.0, 7.5], weights=[1.0, 0.4, 0.2, 0.1]), transfer_to_statespace(b, a, DT))
    u = decaying_triangle(50.0, 10, DT, amplitude=10.0)
    return u, true.simulate(u, DT)[:, 0]


@pytest.fixture(scope="module")
def auto_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stage")
    u, y = _stage_record()
    write_csv(folder / "a.csv", {"V": u, "y": y}, dt=DT)
    args = ["identify", "hysteresis", folder / "a.csv", "--input", "V", "--output", "y", "--model", "pi"]
    args += ["--operators", "4", "--dynamics", "auto", "--creep", "auto", "-o", folder / "s.json"]
    return folder, args, run_main(*args)


def test_auto_search_reports_progress_with_an_estimate_on_stderr(auto_run):
    _, _, (code, out, err) = auto_run
    assert code == 0, err
    lines = err.splitlines()
    counted = [line for line in lines if "held-out candidates" in line]
    assert counted[0].endswith(f"held-out candidates 0/{N_CANDIDATES}")
    assert any(f"1/{N_CANDIDATES}, about" in line and line.endswith(" s left") for line in counted), counted
    assert counted[-1].endswith(f"{N_CANDIDATES}/{N_CANDIDATES}")
    assert lines[0] == counted[0]  # nothing before the count: a refused input prints only its error
    # a log gets a few lines, not one per candidate
    assert len(counted) < N_CANDIDATES // 2, lines
    assert "candidate" not in out.split("held-out RMS error")[0]  # progress stays off stdout


def test_auto_summary_is_a_short_table_with_the_chosen_candidate(auto_run):
    _, _, (code, out, err) = auto_run
    rows = [line for line in out.splitlines() if line.startswith("    ") and line.strip()[0].isdigit()]
    assert SUMMARY_CANDIDATES <= len(rows) <= SUMMARY_CANDIDATES + 1, out
    assert sum("<- chosen" in row for row in rows) == 1, out
    assert f"more of {N_CANDIDATES} candidates" in out
    assert len(out.splitlines()) < N_CANDIDATES, out  # was one line per candidate


def test_quiet_prints_no_progress(auto_run):
    folder, args, _ = auto_run
    code, out, err = run_main(*args, "--quiet")
    assert code == 0 and out == "" and "candidates" not in err, err


def test_progress_callback_counts_every_candidate_once():
    u, y = _stage_record()
    calls = []
    fit = StageIdentifier("pi", n_operators=4, dynamics="auto", creep=None, sample_time=DT).fit(
        (u, y), progress=lambda step, done, total: calls.append((step, done, total))
    )
    counted = [(done, total) for step, done, total in calls if step == "held-out candidates"]
    assert counted == [(i, len(AUTO_ORDERS)) for i in range(len(AUTO_ORDERS) + 1)]
    assert len(fit.held_out) == len(AUTO_ORDERS)
    assert calls[0][0] == "hysteresis thresholds"


def test_the_table_keeps_the_chosen_candidate_when_it_is_not_among_the_best():
    u, y = _stage_record()
    fit = StageIdentifier("pi", n_operators=4, dynamics="auto", creep=None, sample_time=DT).fit((u, y))
    worst = max(fit.held_out, key=lambda c: c[2])
    tweaked = replace(fit, chosen=(worst[0], tuple(worst[1])))
    table = tweaked.candidate_table(1)
    rows = [line for line in table if "<- chosen" in line or line.strip()[:1].isdigit()]
    assert len(rows) == 2 and "<- chosen" in rows[-1] and rows[-1].split()[0] == str(worst[0])
    assert len(fit.candidate_table()) == len(fit.held_out) + 2  # all of them: header lines and rows


def test_the_report_lists_every_candidate(auto_run):
    folder, args, _ = auto_run
    code, _, err = run_main(*args, "--quiet", "--report", folder / "report")
    assert code == 0, err
    page = (folder / "report" / "index.html").read_text()
    table = page.split("Held-out candidates</h2>")[1].split("</table>")[0]
    assert table.count("<tr>") == N_CANDIDATES + 1  # the header and one row per candidate
    assert table.count("<td>chosen</td>") == 1
