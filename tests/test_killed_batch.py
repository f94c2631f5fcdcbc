"""Tests written to kill survivors of the ``batch`` mutation group (tests/MUTATION.md)."""

import json

import pytest

from stageid.batch.state import FORMAT, STATE_FILE, load_state, save_state


@pytest.mark.parametrize(
    "text",
    [
        "[1, 2]",  # JSON, but not an object
        '"jobs"',
        json.dumps({"format": "another-tool/1", "jobs": {"a": {"command": "x"}}}),  # a foreign state
        json.dumps({"jobs": {"a": {"command": "x"}}}),  # no format
        json.dumps({"format": FORMAT, "jobs": [1]}),  # jobs not an object
    ],
)
def test_a_state_file_that_is_not_ours_means_every_job_runs_again(tmp_path, text):
    (tmp_path / STATE_FILE).write_text(text)
    assert load_state(tmp_path) == {}


def test_the_state_round_trips(tmp_path):
    jobs = {"a": {"command": "frf a.csv", "stageid": "1.0", "inputs": [["a.csv", "00"]], "output": "ff"}}
    save_state(tmp_path, jobs)
    assert load_state(tmp_path) == jobs
