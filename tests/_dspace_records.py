"""The dSPACE piezo records of ``../shared/data/piezo_dspace_preisach`` as the real-data tests use them."""

from __future__ import annotations

import numpy as np
import pytest


def dspace_record(name: str) -> tuple[np.ndarray, np.ndarray, float]:
    """``(u, y, dt)`` of ``<name>.mat`` from 0.1 s before the drive first moves to 10 samples
    before the end (the trimming of ``studies/hysteresis/run_study.py``); skips the test when the
    shared data are absent."""
    from stageid.data.datasets import SHARED_DATA, load_dspace_piezo

    folder = None if SHARED_DATA is None else SHARED_DATA / "piezo_dspace_preisach"
    if folder is None or not folder.is_dir():
        pytest.skip("shared/data/piezo_dspace_preisach not found")
    exp = load_dspace_piezo(folder / f"{name}.mat")
    u, y = exp.u[:, 0], exp.y[:, 0]
    start = max(0, int(np.flatnonzero(np.abs(np.diff(u)) > 1e-9)[0]) - int(round(0.1 / exp.dt)))
    return u[start:-10], y[start:-10], exp.dt
