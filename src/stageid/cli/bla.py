"""``stageid frf --method bla``: read the realisations one at a time and estimate the best linear approximation."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .._errors import DataError

__all__ = ["bla_command", "estimate_bla", "read_design"]


def bla_command(
    paths: Sequence[str],
    inputs: Sequence[str],
    outputs: Sequence[str],
    ts: float | None,
    timing: tuple[int | None, int | None, str | None],
    design_path: str | None,
    scheduler: str | None,
    output: str,
) -> None:
    """``stageid frf --method bla``: check the options, estimate, say the findings, write the table."""
    import click

    from ._common import say
    from .outputs import write_table_output

    periods, transient_periods, transient = timing
    if scheduler is not None:
        raise click.UsageError("--scheduler applies to --method welch on chunked records; got --method bla.")
    if transient == "lpm" and transient_periods is not None:
        raise click.UsageError("--transient-periods applies to --transient drop; got --transient lpm.")
    result = estimate_bla(paths, inputs, outputs, ts, periods, transient_periods, design_path, transient or "drop")
    for line in result.summary().splitlines():
        say(line)
    write_table_output(output, result.to_columns())
    say(f"best linear approximation written to {output}")


def read_design(path: str | None) -> dict[str, Any]:
    """The ``.multisine.json`` written by ``stageid signal multisine`` ({} without one)."""
    if path is None:
        return {}
    if not Path(path).is_file():
        raise DataError(f"--design '{path}' does not exist (the .multisine.json of stageid signal multisine).")
    try:
        design = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise DataError(f"--design '{path}' is not a readable multisine design JSON: {exc}.") from None
    needed = ("n_periods", "excited_lines", "experiments_per_realisation")
    missing = [k for k in needed if k not in design] if isinstance(design, dict) else list(needed)
    if missing:
        raise DataError(f"--design '{path}' lacks {', '.join(missing)}; expected the JSON of stageid signal multisine.")
    return design


def estimate_bla(
    paths: Sequence[str],
    inputs: Sequence[str],
    outputs: Sequence[str],
    ts: float | None,
    periods: int | None,
    transient_periods: int | None,
    design_path: str | None,
    transient: str = "drop",
):
    """Group the files into realisations (in the given order), add each, return the BLAResult."""
    from ..frf.bla import BLAAccumulator
    from .progress import is_interactive, progress

    design = read_design(design_path)
    group = int(design.get("experiments_per_realisation", len(inputs)))
    if len(paths) % group:
        raise DataError(
            f"{len(paths)} files do not form realisations of {group} experiment(s) each; "
            "expected a whole number of realisations, files of one realisation next to each other."
        )
    lines = {}
    if design:
        lines = {
            "excited": design["excited_lines"],
            "detection_odd": design.get("detection_odd_lines", []),
            "detection_even": design.get("detection_even_lines", []),
        }
    acc = BLAAccumulator(periods or design.get("n_periods"), transient_periods, transient=transient, **lines)
    # tqdm costs a tenth of a second to import: only for a terminal that shows it
    bar = progress(len(paths) // group, desc="realisations") if is_interactive() else None
    for start in range(0, len(paths), group):
        acc.add([_read_record(p, inputs, outputs, ts) for p in paths[start : start + group]])
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return acc.result()


def _read_record(path: str, inputs: Sequence[str], outputs: Sequence[str], ts: float | None):
    """An NPZ of 1-D float columns as memory-mapped channels (no table copy), else an Experiment."""
    from ..data.sampling import UNIFORM_RTOL
    from ..frf.records import read_npz_record
    from ._common import current_trim, read_experiments

    # the memory-mapped path reads whole columns; a --start/--stop window goes through the table reader
    direct = str(path).lower().endswith(".npz") and current_trim() == (None, None)
    record = read_npz_record(path, inputs, outputs, ts, UNIFORM_RTOL) if direct else None
    return record if record is not None else read_experiments([path], inputs, outputs, ts)[0]
