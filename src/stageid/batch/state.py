"""What a finished job depended on, so a second run can skip it: the batch's state file.

A job is up to date when its command, the content (SHA-256) of every input file, the stageid
version and its output file are what they were when it last succeeded.  The state lives in
``DIR/.stageid-batch.json`` and is replaced atomically, so an interrupted batch leaves the last
complete state; jobs finished before the interruption are then skipped by the next run.
"""

from __future__ import annotations

import contextvars
import hashlib
import json
import os
from collections.abc import Iterable
from pathlib import Path

from ..atomic import atomic_write, atomic_write_text

__all__ = ["STATE_FILE", "FORMAT", "content_hash", "fingerprint", "load_state", "save_state", "write_now"]

STATE_FILE = ".stageid-batch.json"
FORMAT = "stageid.batch-state/1"
_BLOCK = 1 << 20


def content_hash(path: str | os.PathLike[str]) -> str | None:
    """SHA-256 of a file, or of a folder's files (names and contents); None when it cannot be read.

    A missing input is not the batch's error to report: the job runs and fails with the
    command's own message.
    """
    digest = hashlib.sha256()
    root = Path(path)
    try:
        if root.is_dir():  # a directory store (Zarr): every file, in a fixed order
            for item in sorted(p for p in root.rglob("*") if p.is_file()):
                digest.update(str(item.relative_to(root)).encode() + b"\0")
                _feed(digest, item)
        else:
            _feed(digest, root)
    except OSError:
        return None
    return digest.hexdigest()


def _feed(digest, path: Path) -> None:
    with open(path, "rb") as fh:
        while block := fh.read(_BLOCK):
            digest.update(block)


def fingerprint(command: str, inputs: Iterable[tuple[str, str]], version: str) -> dict:
    """What a job's result depends on: command, stageid version, each input's content hash."""
    return {
        "command": command,
        "stageid": version,
        "inputs": [[given, content_hash(absolute)] for given, absolute in inputs],
    }


def load_state(folder: str | os.PathLike[str]) -> dict[str, dict]:
    """The recorded jobs of ``folder`` (name -> fingerprint plus ``output`` hash); {} when unusable.

    A missing, corrupt or foreign state file only means that every job runs again.
    """
    try:
        state = json.loads((Path(folder) / STATE_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(state, dict) or state.get("format") != FORMAT or not isinstance(state.get("jobs"), dict):
        return {}
    return state["jobs"]


def save_state(folder: str | os.PathLike[str], jobs: dict[str, dict]) -> None:
    """Replace the state file atomically (at once, also inside a command's output transaction)."""
    text = json.dumps({"format": FORMAT, "jobs": jobs}, indent=1, sort_keys=True)
    contextvars.Context().run(atomic_write_text, Path(folder) / STATE_FILE, text)


def write_now(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically and now.

    The ``stageid`` command commits its outputs together at its end (one transaction); a
    batch commits each job's output as soon as the job finishes, so an interrupted batch
    keeps the jobs it finished.  An empty context has no transaction to defer to.
    """
    return contextvars.Context().run(atomic_write, path, lambda fh: fh.write(data), binary=True)
