"""Browser sessions of ``stageid serve``: one private workspace per cookie, and safe file names.

Every browser session (a random cookie) gets its own folder under the server's scratch
folder; its prepared records, estimated models and exports live there and nowhere else, so
two tabs with different cookies never see each other's work.  Names that come from the page
are checked here: an upload name is one plain file name, and a record name must resolve to a
file inside the served folder (no ``..``, no absolute path, no symbolic link leading out).
"""

from __future__ import annotations

import re
import secrets
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._errors import DataError

__all__ = ["Session", "SessionStore", "RECORD_SUFFIXES", "upload_name", "record_path", "list_records"]

#: Extensions the data board reads (the package's table readers and FRF tables).
RECORD_SUFFIXES = (".csv", ".npz", ".mat", ".h5", ".hdf5")
_SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,120}$")
_MAX_LISTED = 500


@dataclass(eq=False)
class Session:
    """The state of one browser session: its workspace folder and what the boards made in it.

    ``datasets`` maps a data name (``d1``, ...) to its description (kind ``time`` or ``frd``,
    file, channels); ``models`` maps a model name (``m1``, ...) to its description; ``jobs``
    maps a job id to its :class:`~stageid.app.jobs.Job`.
    """

    key: str
    workspace: Path
    datasets: dict[str, dict[str, Any]] = field(default_factory=dict)
    models: dict[str, dict[str, Any]] = field(default_factory=dict)
    jobs: dict[str, Any] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)
    _counter: int = 0

    def next_name(self, prefix: str) -> str:
        """A fresh name ``prefix<k>`` (``d1``, ``m2``, ``j3`` ...), unique within the session."""
        with self.lock:
            self._counter += 1
            return f"{prefix}{self._counter}"

    @property
    def uploads(self) -> Path:
        folder = self.workspace / "uploads"
        folder.mkdir(exist_ok=True)
        return folder


class SessionStore:
    """Sessions by cookie value; a request without a known cookie starts a new session."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self._sessions: dict[str, Session] = {}
        self._lock = threading.Lock()

    def get(self, key: str | None) -> Session | None:
        with self._lock:
            return self._sessions.get(key) if key else None

    def new(self) -> Session:
        key = secrets.token_urlsafe(18)
        workspace = self.root / f"s{len(self._sessions) + 1}-{secrets.token_hex(4)}"
        workspace.mkdir(parents=True)
        session = Session(key, workspace)
        with self._lock:
            self._sessions[key] = session
        return session

    def all(self) -> list[Session]:
        with self._lock:
            return list(self._sessions.values())


def upload_name(name: str) -> str:
    """An upload's file name, checked: one plain name with a record extension, no folders.

    Raises
    ------
    DataError
        A name with a folder part, ``..``, characters other than letters, digits and ``._+-``,
        or an extension the data board does not read.
    """
    if not _SAFE_NAME.match(name or "") or ".." in name:
        raise DataError(
            f"upload name {name!r} is not a plain file name; expected letters, digits and ._+- without folders."
        )
    suffix = Path(name).suffix.lower()
    if suffix not in RECORD_SUFFIXES:
        raise DataError(f"upload {name!r} has extension {suffix or 'none'!r}; expected {', '.join(RECORD_SUFFIXES)}.")
    return name


def record_path(folder: Path, name: str) -> Path:
    """The file ``name`` (relative, ``/``-separated) inside ``folder``; refuses anything that leaves it.

    Raises
    ------
    DataError
        An absolute name, a name that resolves outside ``folder`` (``..``, symbolic links), or
        no such file.
    """
    root = folder.resolve()
    candidate = (root / name).resolve()
    if Path(name).is_absolute() or not candidate.is_relative_to(root) or candidate == root:
        raise DataError(f"record {name!r} is outside the served folder; expected a file listed by the data board.")
    if not candidate.is_file():
        raise DataError(f"record {name!r} does not exist in the served folder.")
    return candidate


def list_records(folder: Path, suffixes: tuple[str, ...] = RECORD_SUFFIXES) -> list[str]:
    """Files under ``folder`` with one of ``suffixes`` (relative ``/`` names, sorted), at most a few hundred."""
    root = folder.resolve()
    found = []
    for path in sorted(root.rglob("*")):
        if path.suffix.lower() in suffixes and path.is_file() and path.resolve().is_relative_to(root):
            found.append(path.relative_to(root).as_posix())
            if len(found) >= _MAX_LISTED:
                break
    return found
