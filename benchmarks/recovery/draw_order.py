"""The order in which the recovery benchmark starts its draws: longest first.

With two workers, a long draw started last keeps one worker busy while the other idles; started
first, the short ones fill in around it (longest-processing-time-first list scheduling).  A
draw's length is taken from the last run: the seconds column of the draw tables that
``run.py --draw-tables`` writes (``## <label>: draws``).
"""

from __future__ import annotations

import math
import pathlib

import numpy as np

__all__ = ["previous_seconds", "longest_first"]


def previous_seconds(path: pathlib.Path | None) -> dict[tuple[str, int], float]:
    """``{(estimator label, seed): seconds}`` from the draw tables (``## <label>: draws``, as
    :func:`format_draws` writes them) of ``path``; empty when it is absent."""
    if path is None or not path.exists():
        return {}
    found, label = {}, None
    for line in path.read_text().splitlines():
        if line.startswith("## "):
            label = line[3:].removesuffix(": draws") if line.endswith(": draws") else None
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if label and len(cells) >= 7 and cells[0].isdigit():
            try:
                found[(label, int(cells[0]))] = float(cells[6])
            except ValueError:
                continue
    return found


def longest_first(tasks: list[tuple], labels: dict[str, str], seconds: dict[tuple[str, int], float]) -> list[tuple]:
    """``tasks`` (module or tuple of modules, seed, ...) ordered by their expected seconds, longest first: a draw's own
    from ``seconds`` (keyed by estimator label and seed), else its estimator's median there,
    else first of all (an estimator never timed may be the longest)."""
    medians = {}
    for module, label in labels.items():
        known = [v for (lab, _), v in seconds.items() if lab == label]
        medians[module] = float(np.median(known)) if known else math.inf

    def one(module, seed):
        return seconds.get((labels.get(module, ""), seed), medians.get(module, math.inf))

    def expected(task):  # a shared draw (a tuple of modules) takes its cases' sum
        modules = task[0] if isinstance(task[0], tuple) else (task[0],)
        return sum(one(m, task[1]) for m in modules)

    return sorted(tasks, key=expected, reverse=True)  # stable: ties keep the given order
