"""The batch manifest: a CSV file of jobs, one ``name,command`` row each.

``name`` names the job's output (``DIR/<name>.json`` or ``DIR/<name>.csv``) and its row in
``summary.csv``; ``command`` is a stageid command line without ``stageid`` and without ``-o``,
split as a POSIX shell would split it (quote paths with spaces).  When ``command`` is the last
column its commas need no CSV quoting (``a,frf a.csv --inputs Z,Rx --outputs z,rx`` is one
job); elsewhere a command with commas is quoted as CSV quotes it.  Other columns are ignored
(notes, serial numbers).  Everything here is checked before any job runs or any file is
written: a bad manifest is one :class:`~stageid.DataError`.
"""

from __future__ import annotations

import csv
import os
import shlex
from dataclasses import dataclass
from pathlib import Path

from .._errors import DataError

__all__ = ["ManifestRow", "read_manifest", "check_job_name", "REQUIRED_COLUMNS", "RESERVED_NAMES"]

#: The columns every manifest has (in any order; other columns are ignored).
REQUIRED_COLUMNS = ("name", "command")
#: Names whose output would collide with the batch's own files in DIR.
RESERVED_NAMES = ("summary",)
_MAX_NAME = 200
# Characters that are path separators or refused by one of the common file systems.
_FORBIDDEN = set('/\\<>:"|?*')


@dataclass(frozen=True)
class ManifestRow:
    """One job of the manifest: its name, its command line split into words, and its row number."""

    name: str
    command: str
    words: tuple[str, ...]
    row: int


def check_job_name(name: str, row: int) -> str:
    """A job name that is safe as a file name in DIR, or a :class:`DataError` saying why not.

    Refused: empty names, path separators and characters refused by common file systems,
    control characters, a leading dot (DIR's hidden files are the batch's own state), leading
    or trailing blanks, and the reserved name ``summary``.
    """
    where = f"manifest row {row}"
    if not name:
        raise DataError(f"{where}: the name is empty; expected a file-name-safe job name.")
    bad = sorted({c for c in name if c in _FORBIDDEN or ord(c) < 32 or ord(c) == 127})
    if bad:
        raise DataError(
            f"{where}: name {name!r} contains {bad[0]!r}; expected a plain file name "
            '(no path separators, no control characters, none of < > : " | ? *).'
        )
    if name.startswith(".") or name != name.strip():
        raise DataError(f"{where}: name {name!r} starts with a dot or a blank; expected a plain file name.")
    if len(name) > _MAX_NAME:
        raise DataError(f"{where}: name of {len(name)} characters; expected at most {_MAX_NAME}.")
    if name.casefold() in RESERVED_NAMES:
        raise DataError(f"{where}: name {name!r} is reserved for the batch's summary; expected another name.")
    return name


def read_manifest(path: str | os.PathLike[str]) -> list[ManifestRow]:
    """The rows of a manifest CSV file, checked: columns, names (distinct, file-name safe), quoting.

    Row numbers count the header as row 1, as a spreadsheet shows them.  Blank lines are
    skipped; a manifest without jobs is an error.

    Raises
    ------
    DataError
        A missing file, missing ``name``/``command`` columns, an empty or unsafe name, a name
        given twice (also when they differ only in case), an empty or unbalanced command.
    """
    source = Path(path)
    try:
        text = source.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DataError(f"manifest '{source}' does not exist; expected a CSV file with columns name,command.") from None
    except UnicodeDecodeError:
        raise DataError(
            f"manifest '{source}' is not UTF-8 text; expected a CSV file with columns name,command."
        ) from None
    reader = csv.reader(text.splitlines())
    header = [h.strip() for h in next(reader, [])]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        shown = ",".join(header) if header else "nothing"
        raise DataError(
            f"manifest '{source}' has no column {missing[0]!r}; expected columns name,command; got {shown}."
        )
    index = {c: header.index(c) for c in REQUIRED_COLUMNS}
    rows: list[ManifestRow] = []
    seen: dict[str, int] = {}
    for number, fields in enumerate(reader, start=2):
        if not any(f.strip() for f in fields):
            continue
        if len(fields) > len(header) and header[-1] == "command":  # commas of the command line, unquoted
            fields = [*fields[: len(header) - 1], ",".join(fields[len(header) - 1 :])]
        if len(fields) != len(header):
            raise DataError(
                f"manifest row {number}: {len(fields)} fields; expected {len(header)} as in the header "
                "(quote a command that holds commas unless command is the last column)."
            )
        name = check_job_name(fields[index["name"]], number)
        if name.casefold() in seen:
            raise DataError(
                f"manifest row {number}: name {name!r} is already used in row {seen[name.casefold()]}; "
                "expected distinct names (also ignoring case)."
            )
        seen[name.casefold()] = number
        command = fields[index["command"]].strip()
        rows.append(ManifestRow(name, command, _split(command, name, number), number))
    if not rows:
        raise DataError(f"manifest '{source}' has no jobs; expected at least one name,command row.")
    return rows


def _split(command: str, name: str, row: int) -> tuple[str, ...]:
    try:
        words = tuple(shlex.split(command))
    except ValueError as exc:
        raise DataError(f"manifest row {row} ({name}): command cannot be split into words ({exc}).") from None
    if not words:
        raise DataError(f"manifest row {row} ({name}): the command is empty; expected a stageid command line.")
    return words
