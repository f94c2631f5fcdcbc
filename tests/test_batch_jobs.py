"""Manifest rows to jobs: which words are input paths (made absolute), the output's extension,
and the content hash that decides skipping.  No cluster needed."""

from __future__ import annotations

import os

import pytest

from stageid._errors import DataError
from stageid.batch import ManifestRow, resolve_job
from stageid.batch.state import content_hash
from stageid.cli.main import cli

BASE = os.path.abspath("/data/fleet")


def job(command: str):
    import shlex

    return resolve_job(ManifestRow("j", command, tuple(shlex.split(command)), 2), cli, BASE)


def test_positional_paths_and_path_options_are_made_absolute_and_nothing_else():
    j = job(
        "identify closed-loop ex1.csv sub/ex2.csv --references rx --outputs x "
        "--controller K.json --ts 0.001 --plant-inputs u.csv"
    )
    assert j.verb == "identify closed-loop" and j.suffix == ".json"
    assert j.argv[:4] == ("identify", "closed-loop", f"{BASE}/ex1.csv", f"{BASE}/sub/ex2.csv")
    assert f"{BASE}/K.json" in j.argv and "u.csv" in j.argv  # --plant-inputs is a column list, not a path
    assert j.inputs == (
        ("ex1.csv", f"{BASE}/ex1.csv"),
        ("sub/ex2.csv", f"{BASE}/sub/ex2.csv"),
        ("K.json", f"{BASE}/K.json"),
    )


def test_option_with_equals_absolute_paths_and_two_fixed_arguments():
    j = job("identify closed-loop /abs/ex.csv --controller=K.json --references r --outputs x")
    assert j.argv[2] == "/abs/ex.csv" and f"--controller={BASE}/K.json" in j.argv
    s = job("simulate model.json u.csv --ts 0.002")
    assert s.suffix == ".csv" and s.inputs == (("model.json", f"{BASE}/model.json"), ("u.csv", f"{BASE}/u.csv"))


def test_a_column_named_like_a_file_stays_a_column():
    j = job("identify hysteresis forc.csv --input forc.csv --output y --model pi --operators 8")
    assert j.argv[2:] == (
        f"{BASE}/forc.csv",
        "--input",
        "forc.csv",
        "--output",
        "y",
        "--model",
        "pi",
        "--operators",
        "8",
    )
    assert [given for given, _ in j.inputs] == ["forc.csv"]


@pytest.mark.parametrize(
    "command, suffix",
    [
        ("plants p558", ".json"),
        ("plants p558 --experiment chirp-z --seed 2", ".csv"),
        ("signal prbs --n-samples 500 --dt 0.001", ".csv"),
        ("identify frd frf.csv --order 4 --dt 0.001", ".json"),
        ("freqresp m.json --fmin 1 --fmax 10", ".csv"),
    ],
)
def test_output_extension_by_verb(command, suffix):
    assert job(command).suffix == suffix


def test_signal_kind_that_does_not_exist_is_not_a_verb():
    with pytest.raises(DataError, match="'signal wobble' is not a stageid verb"):
        job("signal wobble --dt 1")


def test_content_hash_follows_content_not_names_or_times(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_bytes(b"t,u\n0,1\n")
    b.write_bytes(b"t,u\n0,1\n")
    assert content_hash(a) == content_hash(b)
    os.utime(a, (0, 0))
    assert content_hash(a) == content_hash(b)
    b.write_bytes(b"t,u\n0,2\n")
    assert content_hash(a) != content_hash(b)
    assert content_hash(tmp_path / "missing.csv") is None


def test_content_hash_of_a_directory_store_sees_every_file(tmp_path):
    store = tmp_path / "rec.zarr"
    (store / "u").mkdir(parents=True)
    (store / "u" / "0").write_bytes(b"\x00\x01")
    before = content_hash(store)
    (store / "u" / "1").write_bytes(b"")  # a new (even empty) chunk changes the hash
    assert content_hash(store) != before


def test_a_last_command_column_needs_no_quotes_for_its_commas(tmp_path):
    from stageid.batch import read_manifest

    (tmp_path / "m.csv").write_text(
        "name,command\n"
        "unit7,identify statespace unit7.csv --inputs Ux,Uy --outputs x,y --order 6\n"
        'quoted,"frf a.csv --inputs Z,Rx --outputs z"\n'
    )
    rows = read_manifest(tmp_path / "m.csv")
    assert rows[0].words == (
        "identify",
        "statespace",
        "unit7.csv",
        "--inputs",
        "Ux,Uy",
        "--outputs",
        "x,y",
        "--order",
        "6",
    )
    assert rows[1].words == ("frf", "a.csv", "--inputs", "Z,Rx", "--outputs", "z")
    assert [r.row for r in rows] == [2, 3]
