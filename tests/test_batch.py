"""`stageid batch` on a real Dask cluster (scheduler + 2 workers on 127.0.0.1): outputs equal to
the direct commands byte for byte, failed rows, skipping, and the one-line errors of bad input."""

from __future__ import annotations

import json
import shutil
import socket
import time

import pytest

from _batch_records import IDENTIFY_Z, read_summary, write_manifest, write_record
from conftest import assert_one_line_error, run_cli, run_main
from dask_cluster import TestCluster


@pytest.fixture(scope="module")
def cluster():
    with TestCluster(n_workers=2) as running:
        yield running


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Three P-558 records, a model and a signal, as a fleet's data folder would hold them."""
    folder = tmp_path_factory.mktemp("fleet")
    write_record(folder, "unit1.csv", "chirp-z", seed=1)
    write_record(folder, "unit2.csv", "chirp-z", seed=2)
    write_record(folder, "unit rx.csv", "chirp-rx", seed=3)
    rc, _, err = run_main("plants", "p558", "-o", folder / "p558.json")
    assert rc == 0, err
    return folder


def _copy(records, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(records, data)
    return data


# one job of each output kind; paths relative to the manifest's folder (one with a blank, quoted)
JOBS = [
    ("unit1", IDENTIFY_Z.format("unit1.csv")),
    ("unit2", IDENTIFY_Z.format("unit2.csv")),
    ("unit-rx", 'identify statespace "unit rx.csv" --inputs Rx --outputs rx --order 4 --horizon 20'),
    ("unit1-frf", "frf unit1.csv --inputs Z --outputs z --segment 512"),
    ("unit1-sim", "simulate p558.json unit1.csv"),
    ("chirp", "signal chirp --f0 1 --f1 50 --duration 1 --dt 0.001"),
]


def _direct(data, command: str, output):
    """The command run directly in the manifest's folder, as a user would type it."""
    import shlex

    return run_main(*shlex.split(command), "-o", output, cwd=data)


def test_outputs_equal_the_direct_commands_byte_for_byte(cluster, records, tmp_path):
    data = _copy(records, tmp_path)
    manifest = write_manifest(data / "fleet.csv", JOBS)
    rc, out, err = run_main("batch", manifest, "--out", tmp_path / "out", "--scheduler", cluster.address)
    assert rc == 0, err
    assert "6 ok, 0 skipped, 0 failed" in out
    for name, command in JOBS:
        suffix = ".json" if command.startswith("identify") else ".csv"
        rc, _, err = _direct(data, command, tmp_path / f"direct{suffix}")
        assert rc == 0, err
        assert (tmp_path / "out" / f"{name}{suffix}").read_bytes() == (tmp_path / f"direct{suffix}").read_bytes(), name
    rows = read_summary(tmp_path / "out")
    assert [r["name"] for r in rows] == [name for name, _ in JOBS]  # manifest order
    assert {r["status"] for r in rows} == {"ok"} and {r["error"] for r in rows} == {""}
    workers = {w for w in _worker_addresses(cluster)}
    assert {r["worker"] for r in rows} <= workers and all(float(r["seconds"]) > 0 for r in rows)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(
        [
            ".stageid-batch.json",
            "summary.csv",
            *(n + (".json" if c.startswith("identify") else ".csv") for n, c in JOBS),
        ]
    )


def _worker_addresses(cluster) -> set[str]:
    from distributed import Client

    with Client(cluster.address, set_as_default=False) as client:
        return set(client.scheduler_info()["workers"])


def test_a_failing_job_is_a_row_with_the_direct_commands_error(cluster, records, tmp_path):
    data = _copy(records, tmp_path)
    (data / "broken.csv").write_text("t,Z,z\n0,1,2\n0.002,nan,3\n0.004,1,2\n")
    jobs = [
        ("good", IDENTIFY_Z.format("unit1.csv")),
        ("nan", IDENTIFY_Z.format("broken.csv")),
        ("missing", IDENTIFY_Z.format("nowhere.csv")),
        ("column", "identify statespace unit1.csv --inputs Q --outputs z --order 4"),
        ("good2", "frf unit2.csv --inputs Z --outputs z --segment 512"),
    ]
    manifest = write_manifest(data / "fleet.csv", jobs)
    rc, out, err = run_main("batch", manifest, "--out", tmp_path / "out", "--scheduler", cluster.address)
    assert rc == 1, err
    assert "2 ok, 0 skipped, 3 failed" in out
    rows = {r["name"]: r for r in read_summary(tmp_path / "out")}
    assert [rows[n]["status"] for n, _ in jobs] == ["ok", "failed", "failed", "failed", "ok"]
    for name, command in jobs[1:4]:
        rc, _, direct_err = _direct(data, command, tmp_path / "direct.json")
        assert rc == 2
        assert rows[name]["error"] == direct_err.strip().removeprefix("stageid: error: ")
        assert "\n" not in rows[name]["error"] and rows[name]["error"]
        assert not (tmp_path / "out" / f"{name}.json").exists()
    assert (tmp_path / "out" / "good.json").exists() and (tmp_path / "out" / "good2.csv").exists()


def test_a_second_run_skips_exactly_the_unchanged_jobs(cluster, records, tmp_path):
    data = _copy(records, tmp_path)
    jobs = [("a", IDENTIFY_Z.format("unit1.csv")), ("b", IDENTIFY_Z.format("unit2.csv")), ("c", JOBS[2][1])]
    manifest = write_manifest(data / "fleet.csv", jobs)
    out_dir = tmp_path / "out"

    def run():
        rc, _, err = run_main("batch", manifest, "--out", out_dir, "--scheduler", cluster.address)
        assert rc == 0, err
        return {r["name"]: r["status"] for r in read_summary(out_dir)}

    assert run() == {"a": "ok", "b": "ok", "c": "ok"}
    first = {p.name: p.read_bytes() for p in out_dir.glob("*.json")}
    assert run() == {"a": "skipped", "b": "skipped", "c": "skipped"}
    assert {p.name: p.read_bytes() for p in out_dir.glob("*.json")} == first
    write_record(data, "unit1.csv", "chirp-z", seed=11)  # new content in a's input
    assert run() == {"a": "ok", "b": "skipped", "c": "skipped"}
    assert (out_dir / "a.json").read_bytes() != first["a.json"]
    write_manifest(
        manifest, [jobs[0], ("b", IDENTIFY_Z.format("unit2.csv").replace("--order 4", "--order 5")), jobs[2]]
    )
    assert run() == {"a": "skipped", "b": "ok", "c": "skipped"}
    (out_dir / "c.json").write_text("{}")  # an edited output is not up to date
    assert run() == {"a": "skipped", "b": "skipped", "c": "ok"}
    assert (out_dir / "c.json").read_bytes() == first["c.json"]
    (out_dir / ".stageid-batch.json").write_text("not json")  # a broken state: everything runs again
    assert run() == {"a": "ok", "b": "ok", "c": "ok"}


def test_input_paths_are_read_relative_to_the_manifest_not_the_working_directory(cluster, records, tmp_path):
    data = _copy(records, tmp_path)
    manifest = write_manifest(data / "fleet.csv", [("a", IDENTIFY_Z.format("unit1.csv"))])
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    rc, _, err = run_main("batch", manifest, "--out", "out", "--scheduler", cluster.address, cwd=elsewhere)
    assert rc == 0, err
    assert (elsewhere / "out" / "a.json").exists()
    state = json.loads((elsewhere / "out" / ".stageid-batch.json").read_text())
    assert state["jobs"]["a"]["inputs"][0][0] == "unit1.csv"  # recorded as the manifest gives it


def test_local_cluster_by_the_real_script(records, tmp_path):
    """No --scheduler: a local cluster of worker processes, started and closed by the command."""
    data = _copy(records, tmp_path)
    manifest = write_manifest(data / "fleet.csv", [("a", IDENTIFY_Z.format("unit1.csv")), ("f", JOBS[3][1])])
    rc, out, err = run_cli("batch", manifest, "--out", tmp_path / "out", "--workers", "1", timeout=300)
    assert rc == 0, err
    assert err == ""  # no Dask warnings or logs (stderr is not a terminal: no progress bar either)
    assert "2 ok" in out
    rows = read_summary(tmp_path / "out")
    assert [r["status"] for r in rows] == ["ok", "ok"] and rows[0]["worker"] == rows[1]["worker"] != ""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler_is_one_line_within_10_s_and_writes_nothing(records, tmp_path):
    data = _copy(records, tmp_path)
    manifest = write_manifest(data / "fleet.csv", [("a", IDENTIFY_Z.format("unit1.csv"))])
    start = time.monotonic()
    rc, _, err = run_cli("batch", manifest, "--out", tmp_path / "out", "--scheduler", f"tcp://127.0.0.1:{_free_port()}")
    assert time.monotonic() - start < 10  # the whole process, imports included
    assert_one_line_error(rc, err, "cannot reach the Dask scheduler")
    assert not (tmp_path / "out").exists()


BAD_MANIFESTS = {
    "no command column": ("name,cmd\na,frf x.csv --inputs u --outputs y\n", "no column 'command'"),
    "no columns": ("\n", "no column 'name'"),
    "no jobs": ("name,command\n", "no jobs"),
    "duplicate": ("name,command\na,frf x.csv --inputs u --outputs y\na,frf y.csv --inputs u --outputs y\n", "row 2"),
    "duplicate by case": (
        "name,command\nUnit,frf x.csv --inputs u --outputs y\nunit,frf x.csv --inputs u --outputs y\n",
        "ignoring case",
    ),
    "not a verb": ("name,command\na,fit x.csv\n", "'fit' is not a stageid verb"),
    "stageid prefix": ("name,command\na,stageid frf x.csv --inputs u --outputs y\n", "not a stageid verb"),
    "batch itself": ("name,command\na,batch other.csv --out o\n", "cannot run in a batch"),
    "a report": ("name,command\na,report m.json x.csv --out r\n", "cannot run in a batch"),
    "export": ("name,command\na,export c m.json\n", "cannot run in a batch"),
    "a group": ("name,command\na,identify\n", "not a stageid verb"),
    "-o": ("name,command\na,frf x.csv --inputs u --outputs y -o f.csv\n", "expected no -o"),
    "-o glued": ("name,command\na,frf x.csv --inputs u --outputs y -of.csv\n", "expected no -o"),
    "--output=": ("name,command\na,frf x.csv --inputs u --outputs y --output=f.csv\n", "expected no -o"),
    "--output-file": (
        "name,command\na,identify hysteresis x.csv --input V --output y --output-file h.json\n",
        "expected no -o",
    ),
    "--report": ("name,command\na,identify statespace x.csv --inputs u --outputs y --report r\n", "--report"),
    "--help": ("name,command\na,frf --help\n", "--help"),
    "unknown option": ("name,command\na,frf x.csv --inputs u --outputs y --nope 3\n", "--nope"),
    "missing option": ("name,command\na,frf x.csv --outputs y\n", "--inputs"),
    "bad value": ("name,command\na,frf x.csv --inputs u --outputs y --segment many\n", "many"),
    "slash": ("name,command\na/b,frf x.csv --inputs u --outputs y\n", "'/'"),
    "dotdot": ("name,command\n..,frf x.csv --inputs u --outputs y\n", "starts with a dot"),
    "backslash": ("name,command\na\\b,frf x.csv --inputs u --outputs y\n", "'\\\\'"),
    "hidden": ("name,command\n.state,frf x.csv --inputs u --outputs y\n", "starts with a dot"),
    "summary": ("name,command\nsummary,frf x.csv --inputs u --outputs y\n", "reserved"),
    "empty name": ("name,command\n,frf x.csv --inputs u --outputs y\n", "name is empty"),
    "empty command": ("name,command\na,\n", "command is empty"),
    "quote": ('name,command\na,"frf ""x.csv --inputs u --outputs y"\n', "cannot be split"),
    "ragged": ("command,name\nfrf x.csv,a,extra\n", "3 fields"),
}


@pytest.mark.parametrize("case", sorted(BAD_MANIFESTS))
def test_bad_manifest_is_one_line_and_nothing_is_written(tmp_path, case):
    text, fragment = BAD_MANIFESTS[case]
    (tmp_path / "m.csv").write_text(text)
    rc, _, err = run_main("batch", tmp_path / "m.csv", "--out", tmp_path / "out", warnings_as_errors=True)
    assert_one_line_error(rc, err, fragment)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--workers"),
        (["--scheduler", "127.0.0.1:8786"], "tcp://HOST:PORT"),
        (["--workers", "0"], "--workers"),
    ],
)
def test_bad_options_are_one_line(tmp_path, args, fragment):
    write_manifest(tmp_path / "m.csv", [("a", "frf x.csv --inputs u --outputs y")])
    rc, _, err = run_main("batch", tmp_path / "m.csv", "--out", tmp_path / "out", *args)
    assert_one_line_error(rc, err, fragment)
    assert not (tmp_path / "out").exists()


def test_missing_manifest_and_out_in_a_missing_folder_are_one_line(tmp_path):
    rc, _, err = run_main("batch", tmp_path / "none.csv", "--out", tmp_path / "out")
    assert_one_line_error(rc, err, "does not exist")
    write_manifest(tmp_path / "m.csv", [("a", "frf x.csv --inputs u --outputs y")])
    rc, _, err = run_main("batch", tmp_path / "m.csv", "--out", tmp_path / "no" / "out")
    assert_one_line_error(rc, err, "does not exist")


def test_an_output_that_would_overwrite_an_input_is_refused(records, tmp_path):
    data = _copy(records, tmp_path)
    manifest = write_manifest(data / "fleet.csv", [("p558", "simulate p558.json unit1.csv")])
    (data / "p558.csv").write_bytes((data / "unit1.csv").read_bytes())  # DIR = data: p558.csv would be replaced
    write_manifest(manifest, [("p558", "simulate p558.json p558.csv")])
    before = (data / "p558.csv").read_bytes()
    rc, _, err = run_main("batch", manifest, "--out", data)
    assert_one_line_error(rc, err, "is also an input")
    assert (data / "p558.csv").read_bytes() == before
