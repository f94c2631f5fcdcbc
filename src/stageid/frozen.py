"""A read-only mapping that pickles: what a frozen result holds as its ``diagnostics``.

``types.MappingProxyType`` is read-only too, but cannot be pickled, and results are pickled
(a study's cache, a worker returning a fit).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import Any

__all__ = ["FrozenMapping"]


class FrozenMapping(Mapping[str, Any]):
    """A copy of ``data`` that can be read like a dict and not written.

    Examples
    --------
    >>> d = FrozenMapping({"n_pairs": 4})
    >>> d["n_pairs"], dict(d)
    (4, {'n_pairs': 4})
    >>> d["n_pairs"] = 5
    Traceback (most recent call last):
    ...
    TypeError: 'FrozenMapping' object does not support item assignment
    """

    __slots__ = ("_data",)

    def __init__(self, data: Mapping[str, Any] | Iterable[tuple[str, Any]] = ()) -> None:
        self._data = dict(data)

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"FrozenMapping({self._data!r})"
