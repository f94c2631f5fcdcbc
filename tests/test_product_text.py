"""What the product prints and documents speaks of papers, records and figures: no issue or
session numbers and no dates in the package's source (messages, docstrings, comments).
Figures with dates and history belong in the RESULTS files."""

from __future__ import annotations

import pathlib
import re

import stageid

_PROCESS_WORDS = re.compile(r"\b(?:[Ii]ssue|[Ss]ession|[Ss]print)\s+\d+|\b20\d\d-\d\d-\d\d\b")


def test_source_free_of_issue_numbers_sessions_and_dates():
    root = pathlib.Path(stageid.__file__).parent
    found = [
        f"{path.relative_to(root)}:{i}: {line.strip()}"
        for path in sorted(root.rglob("*.py"))
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if _PROCESS_WORDS.search(line)
    ]
    assert not found, "process words in the product:\n" + "\n".join(found)


def test_the_pattern_catches_what_it_is_for():
    for text in ("see issue 18", "(Session 12)", "measured 2026-12-01"):
        assert _PROCESS_WORDS.search(text), text
    for text in ("eq. 18", "the sessions of two browser tabs", "issue-free"):
        assert not _PROCESS_WORDS.search(text), text
