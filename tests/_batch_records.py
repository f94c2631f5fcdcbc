"""Records and manifests for the batch tests: P-558 experiments written by the CLI itself."""

from __future__ import annotations

import csv
from pathlib import Path

from conftest import run_main


def write_record(folder: Path, name: str, experiment: str = "chirp-z", seed: int = 0) -> Path:
    """``stageid plants p558 --experiment EXPERIMENT --seed SEED -o folder/name``."""
    rc, _, err = run_main("plants", "p558", "--experiment", experiment, "--seed", seed, "-o", folder / name)
    assert rc == 0, err
    return folder / name


def write_manifest(path: Path, rows: list[tuple[str, str]], header: tuple[str, ...] = ("name", "command")) -> Path:
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def read_summary(folder: Path) -> list[dict[str, str]]:
    with open(folder / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


#: A quick identification of the z channel (fixed order and horizon: no selection sweeps).
IDENTIFY_Z = "identify statespace {} --inputs Z --outputs z --order 4 --horizon 20"
