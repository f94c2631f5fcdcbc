"""Atomic outputs: every file stageid writes appears whole or not at all, and never over an input.

One mechanism for every writer of the package (tables, models, reports, the demo folder):

* :func:`atomic_write` writes through a temporary file in the target's folder and renames it
  into place, so a crash or an interrupt never leaves half a file under the target's name.
* :func:`staged_folder` does the same for a folder of files (a report, the demo's outputs).
* :func:`transaction` groups the outputs of one job: inside it, nothing is renamed into place
  until the block ends without an error; then all outputs are moved into place together. An
  error or an interrupt removes the temporaries and leaves existing files byte-identical.  The
  ``stageid`` command runs every verb in one transaction, so a model file is never written
  when its ``--report`` fails.
* Files registered with :func:`note_input` are protected: an output that resolves to one of
  them (``-o`` naming the measurement being read) raises :class:`~stageid.DataError`.

The parent folder of an output must exist (one rule for every writer); it is never created.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from ._errors import DataError

__all__ = [
    "default_mode",
    "check_parent",
    "atomic_write",
    "atomic_write_text",
    "staged_folder",
    "transaction",
    "note_input",
    "check_not_input",
    "same_file",
]


def default_mode(directory: bool = False) -> int:
    """The mode a plain ``open(path, "w")`` (or ``mkdir``) gives; ``mkstemp`` makes files private."""
    umask = os.umask(0)
    os.umask(umask)
    return (0o777 if directory else 0o666) & ~umask


def check_parent(target: str | os.PathLike[str]) -> Path:
    """Return ``target`` as a Path; raise :class:`DataError` when its folder does not exist."""
    path = Path(target)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise DataError(f"cannot write '{path}': directory '{parent}' does not exist.")
    return path


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """True when two paths name one file (symbolic links and ``..`` resolved; hard links by inode)."""
    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
        return os.path.samefile(a, b)
    except OSError:
        return False


class _Transaction:
    """Outputs staged by one job, committed together at its end (see :func:`transaction`)."""

    def __init__(self) -> None:
        self.inputs: list[str] = []
        self.staged: list[tuple[Path, Path, bool]] = []  # (temporary, target, is a folder)
        self.staging_dirs: list[str] = []

    def inside_staging_dir(self, path: Path) -> bool:
        parent = os.path.realpath(path.parent if str(path.parent) else ".")
        return any(parent == d or parent.startswith(d + os.sep) for d in self.staging_dirs)

    def stage(self, tmp: Path, target: Path, folder: bool) -> None:
        check_not_input(target)
        for _, old_target, _ in self.staged:
            if os.path.realpath(old_target) == os.path.realpath(target):
                raise DataError(f"two outputs of this command are both '{target}'; expected distinct names.")
        self.staged.append((tmp, target, folder))

    def commit(self) -> None:
        for tmp, target, folder in self.staged:  # inputs read after an output was staged are checked too
            check_not_input(target)
            for entry in tmp.iterdir() if folder and target.is_dir() else ():
                check_not_input(target / entry.name)
        for tmp, target, folder in self.staged:
            _move_into_place(tmp, target, folder)
        self.staged = []

    def discard(self) -> None:
        for tmp, _, folder in self.staged:
            _remove(tmp, folder)
        self.staged = []


_CURRENT: contextvars.ContextVar[_Transaction | None] = contextvars.ContextVar("stageid_transaction", default=None)


@contextlib.contextmanager
def transaction() -> Iterator[None]:
    """Group the outputs written inside the block; commit them together when it succeeds.

    Examples
    --------
    >>> import os, tempfile
    >>> from stageid.atomic import transaction, atomic_write_text
    >>> d = tempfile.mkdtemp()
    >>> try:
    ...     with transaction():
    ...         _ = atomic_write_text(os.path.join(d, "model.json"), "{}")
    ...         raise RuntimeError("the report failed")
    ... except RuntimeError:
    ...     pass
    >>> os.listdir(d)
    []
    """
    if _CURRENT.get() is not None:  # nested: the outer transaction commits
        yield
        return
    tx = _Transaction()
    token = _CURRENT.set(tx)
    try:
        yield
        tx.commit()
    finally:
        tx.discard()
        _CURRENT.reset(token)


def note_input(path: str | os.PathLike[str]) -> None:
    """Register a file the current job reads; outputs of the job may not overwrite it."""
    tx = _CURRENT.get()
    if tx is not None:
        tx.inputs.append(os.fspath(path))


def check_not_input(target: str | os.PathLike[str]) -> None:
    """Raise :class:`DataError` when ``target`` is a file the current job reads."""
    tx = _CURRENT.get()
    if tx is None:
        return
    for source in tx.inputs:
        if same_file(source, target):
            raise DataError(
                f"output '{target}' is also an input of this command ('{source}'); "
                "expected a different output name (the input is left unchanged)."
            )


def _remove(tmp: Path, folder: bool) -> None:
    if folder:
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _move_into_place(tmp: Path, target: Path, folder: bool) -> None:
    if not folder:
        os.replace(tmp, target)
        return
    if not target.exists():
        os.replace(tmp, target)
        return
    if not target.is_dir():
        raise DataError(f"cannot write into '{target}': it is a file; expected a folder.")
    for entry in sorted(tmp.iterdir()):
        os.replace(entry, target / entry.name)
    tmp.rmdir()


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[Any]], None], *, binary: bool = False) -> Path:
    """Write ``path`` through ``write(fh)`` into a temporary file, then move it into place.

    Outside a :func:`transaction` the file is renamed into place at once; inside one, at the
    transaction's successful end.  Text is UTF-8 without newline translation.

    Raises
    ------
    DataError
        When the folder of ``path`` does not exist, or ``path`` is an input of the current job.
    """
    target = check_parent(path)
    check_not_input(target)
    directory = target.parent if str(target.parent) else Path(".")
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    tmp = Path(name)
    try:
        mode = "wb" if binary else "w"
        with os.fdopen(fd, mode, **({} if binary else {"encoding": "utf-8", "newline": ""})) as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, default_mode())
        tx = _CURRENT.get()
        if tx is None or tx.inside_staging_dir(target):
            os.replace(tmp, target)
        else:
            tx.stage(tmp, target, folder=False)
    except BaseException:
        _remove(tmp, folder=False)
        raise
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, as :func:`atomic_write`."""
    return atomic_write(path, lambda fh: fh.write(text))


@contextlib.contextmanager
def staged_folder(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary folder next to ``path``; its files replace those of ``path`` at the end.

    A folder that does not exist yet is renamed into place whole; an existing one receives the
    new files one by one (other files in it stay).  Inside a :func:`transaction` the move waits
    for the transaction's end.  On an error or interrupt the temporary folder is removed.

    Raises
    ------
    DataError
        When the parent folder does not exist, or ``path`` is an existing file.
    """
    target = check_parent(path)
    if target.exists() and not target.is_dir():
        raise DataError(f"cannot write into '{target}': it is a file; expected a folder.")
    parent = target.parent if str(target.parent) else Path(".")
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=parent))
    tx = _CURRENT.get()
    real = os.path.realpath(tmp)
    try:
        if tx is not None:
            tx.staging_dirs.append(real)
        yield tmp
        os.chmod(tmp, default_mode(directory=True))
        if tx is None or tx.inside_staging_dir(target):
            _move_into_place(tmp, target, folder=True)
        else:
            tx.stage(tmp, target, folder=True)
    except BaseException:
        _remove(tmp, folder=True)
        raise
    finally:
        if tx is not None:
            tx.staging_dirs.remove(real)
