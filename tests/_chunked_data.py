"""Records written as HDF5, Zarr and .npy for the chunked tests, with the same data in memory."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from stageid.data import Experiment
from stageid.data.chunked import ChunkedRecord
from stageid.models import StateSpaceModel

DT = 1e-3
NAMES = ("u1", "u2", "y1", "y2")

#: A 4-state 2x2 stage: two lightly damped modes, each input driving both.
PLANT = StateSpaceModel(
    [[0.9, 0.2, 0, 0], [-0.2, 0.9, 0, 0], [0, 0, 0.8, 0.3], [0, 0, -0.3, 0.8]],
    [[1.0, 0], [0.0, 0.5], [0, 1], [0.3, 0]],
    [[0.1, 0.0, 0.2, 0], [0, 0.1, 0, 0.3]],
    np.zeros((2, 2)),
    dt=DT,
)


def columns(n: int, seed: int = 0, offset: float = 2.5) -> np.ndarray:
    """(n, 4) samples ``[u1 u2 y1 y2]``: white inputs, noisy outputs with an offset (the mean removal is exercised)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 2))
    y = PLANT.simulate(u) + 0.01 * rng.standard_normal((n, 2)) + offset
    return np.hstack([u + 0.3, y])


def experiment(x: np.ndarray) -> Experiment:
    return Experiment(x[:, :2], x[:, 2:], DT, input_names=["u1", "u2"], output_names=["y1", "y2"])


def write(folder: Path, fmt: str, x: np.ndarray) -> Path:
    """``x`` as a chunked record of format ``fmt``: "h5" (dt attribute), "h5-t" (a t dataset),
    "zarr" (dt attribute), "npy-folder" (one .npy per column and t.npy), "npy" (one 2-D array)."""
    n = x.shape[0]
    if fmt in ("h5", "h5-t"):
        import h5py

        path = folder / "rec.h5"
        with h5py.File(path, "w") as f:
            if fmt == "h5":
                f.attrs["dt"] = DT
            else:
                f["t"] = np.arange(n) * DT
            for name, col in zip(NAMES, x.T):
                f.create_dataset(name, data=col, chunks=(max(1, min(n, 977)),))
        return path
    if fmt == "zarr":
        import zarr

        path = folder / "rec.zarr"
        g = zarr.open_group(str(path), mode="w")
        g.attrs["dt"] = DT
        for name, col in zip(NAMES, x.T):
            g.create_array(name, shape=col.shape, dtype="f8", chunks=(1000,))[:] = col
        return path
    if fmt == "npy-folder":
        path = folder / "rec"
        path.mkdir()
        for name, col in zip(NAMES, x.T):
            np.save(path / f"{name}.npy", col)
        np.save(path / "t.npy", np.arange(n) * DT)
        return path
    if fmt == "npy":
        path = folder / "rec.npy"
        np.save(path, x)
        return path
    raise ValueError(fmt)


@dataclasses.dataclass(frozen=True)
class SlowRecord(ChunkedRecord):
    """A chunked record whose every read takes ``delay`` seconds longer: a computation on a
    cluster that lasts long enough to lose a worker in the middle of it."""

    delay: float = 0.05

    def read(self, start: int, stop: int) -> np.ndarray:
        time.sleep(self.delay)
        return super().read(start, stop)


def slowed(record: ChunkedRecord, delay: float) -> SlowRecord:
    return SlowRecord(**dataclasses.asdict(record), delay=delay)
