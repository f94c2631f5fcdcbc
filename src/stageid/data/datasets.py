"""Loaders for the real measured records in the shared data folder (read in place, never copied).

The folder is found by :func:`shared_data_dir`: the environment variable
``STAGEID_SHARED_DATA`` if set, else a ``shared/data`` folder next to one of the parents of
this package's source (``<repo>/../shared/data`` in a development checkout).  ``SHARED_DATA``
is the folder found at import time, or ``None``.  See ``shared/data/README.md`` for the
provenance and licence of each record.

=========================  ===================================================================
``load_dspace_piezo``      piezo actuator, dSPACE struct .mat: input ``V`` [V], output ``y`` [um]
``load_smarthysteresis``   piezo actuator, 150 V 1 Hz sine CSV: input ``V`` [V], output ``y`` [um]
``load_emps``              EMPS positioning system: Table with ``qm``, ``qg``, ``vir`` [, ``pulses_N``]
``load_daisy``             DaISy mechanical sets: CD player arm, flexible structure, robot arm, ball & beam
=========================  ===================================================================
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._errors import DataError
from .columns import time_axis
from .experiment import Experiment
from .io import PathLike
from .sampling import UNIFORM_RTOL
from .table import Table

__all__ = [
    "SHARED_DATA",
    "DAISY_SETS",
    "shared_data_dir",
    "load_dspace_piezo",
    "load_smarthysteresis",
    "load_emps",
    "load_daisy",
]

ENV_VAR = "STAGEID_SHARED_DATA"
# Logged time stamps are single precision: measured step jitter is 3e-5 (EMPS), 1e-4
# (smarthysteresis) and 2e-4 (dSPACE) of dt, within the sample-time rule's UNIFORM_RTOL.


def shared_data_dir() -> Path | None:
    """Locate the shared data folder, or return ``None`` when it is absent.

    Returns
    -------
    pathlib.Path or None
        ``$STAGEID_SHARED_DATA`` when set (and an existing folder); otherwise the first
        ``<parent>/shared/data`` folder found walking up from this file.

    Examples
    --------
    >>> from stageid.data.datasets import shared_data_dir
    >>> folder = shared_data_dir()
    >>> folder is None or (folder / "README.md").exists()
    True
    """
    env = os.environ.get(ENV_VAR, "").strip()
    if env:
        p = Path(env).expanduser()
        return p if p.is_dir() else None
    for parent in Path(__file__).resolve().parents:
        candidate = parent / "shared" / "data"
        if candidate.is_dir():
            return candidate
    return None


SHARED_DATA: Path | None = shared_data_dir()


def _existing(path: PathLike) -> Path:
    p = Path(path)
    if not p.is_file():
        raise DataError(f"file '{p}' does not exist.")
    return p


def _loadmat(p: Path) -> dict:
    import scipy.io

    try:
        return scipy.io.loadmat(p)
    except Exception as exc:  # scipy raises several types for foreign files
        raise DataError(f"file '{p.name}' is not a readable MATLAB .mat file: {exc}.") from None


def _vector(value: object, label: str, where: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf" or arr.ndim > 2 or (arr.ndim == 2 and min(arr.shape) != 1):
        raise DataError(f"{where}{label} must be a numeric vector; got dtype {arr.dtype}, shape {arr.shape}.")
    return arr.astype(float).ravel()


# ============================================================== dSPACE piezo (.mat)
def load_dspace_piezo(path: PathLike) -> Experiment:
    """Load a dSPACE ControlDesk export of the piezo actuator (``piezo_dspace_preisach/*.mat``).

    The file holds one struct (any variable name): ``X.Data`` time [s], ``Y(1).Data``
    displacement [um], ``Y(3).Data`` drive voltage [V]; ``Y(2)`` (a delayed copy) is ignored.

    Parameters
    ----------
    path : str or path-like
        The ``.mat`` file as ControlDesk wrote it.

    Returns
    -------
    Experiment
        Input ``V`` [V], output ``y`` [um], ``dt`` = the capture sampling period
        (1e-4 s in the shared files, checked against ``X.Data``), name = file stem.

    Raises
    ------
    DataError
        Missing file, not exactly one struct, missing fields, unequal lengths, NaN, or time
        stamps that deviate from the grid by more than 1e-3 of dt.

    Examples
    --------
    >>> from stageid.data.datasets import SHARED_DATA, load_dspace_piezo
    >>> if SHARED_DATA is not None:
    ...     exp = load_dspace_piezo(SHARED_DATA / "piezo_dspace_preisach" / "tri50_1.mat")
    ...     assert exp.input_names == ("V",) and exp.dt == 1e-4
    """
    p = _existing(path)
    where = f"file '{p.name}': "
    content = _loadmat(p)
    keys = [k for k in content if not k.startswith("__")]
    if len(keys) != 1:
        raise DataError(f"{where}expected exactly one dSPACE struct variable; got {len(keys)} ({', '.join(keys)}).")
    rec = content[keys[0]]
    if getattr(rec.dtype, "names", None) is None or not {"X", "Y"} <= set(rec.dtype.names):
        raise DataError(
            f"{where}variable '{keys[0]}' is not a dSPACE struct with fields X and Y; got dtype {rec.dtype}."
        )
    rec = rec.ravel()[0]
    x, ys = rec["X"].ravel(), rec["Y"].ravel()
    if x.size < 1 or ys.size < 3:
        raise DataError(f"{where}expected X (time) and at least 3 Y signals; got {x.size} X and {ys.size} Y entries.")
    t = _vector(x[0]["Data"], "X.Data", where)
    disp = _vector(ys[0]["Data"], "Y(1).Data", where)
    volt = _vector(ys[2]["Data"], "Y(3).Data", where)
    if not (t.size == disp.size == volt.size):
        raise DataError(
            f"{where}X.Data, Y(1).Data and Y(3).Data must have one length; got {t.size}, {disp.size}, {volt.size}."
        )
    nominal = None
    if "Capture" in rec.dtype.names:
        cap = rec["Capture"].ravel()[0]
        try:
            nominal = float(np.ravel(cap["SamplingPeriod"])[0]) * float(np.ravel(cap["Downsampling"])[0])
        except (KeyError, ValueError, IndexError, TypeError):
            nominal = None
    return _piezo_experiment(t, volt, disp, nominal, where, p.stem)


def _check_time(t: np.ndarray, where: str) -> None:
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(f"{where}the time stamps have NaN/inf at row {int(bad[0])} (data rows counted from 0).")


def _piezo_experiment(
    t: np.ndarray, volt: np.ndarray, disp: np.ndarray, nominal: float | None, where: str, name: str
) -> Experiment:
    """The piezo records' one shape: drive ``V`` [V] in, displacement ``y`` [um] out, on the grid of ``t``."""
    _check_time(t, where)
    t0, dt = time_axis(t, where, nominal, UNIFORM_RTOL)
    return Experiment(
        u=volt[:, None],
        y=disp[:, None],
        dt=dt,
        input_names=("V",),
        output_names=("y",),
        input_units=("V",),
        output_units=("um",),
        t0=t0,
        name=name,
    )


# ============================================================== smarthysteresis (.csv)
def load_smarthysteresis(path: PathLike) -> Experiment:
    """Load the headerless piezo CSV ``piezo_smarthysteresis/hysteresis_v_150_1hz.csv``.

    Columns: index (empty), time [s], displacement [um], voltage [V].

    Parameters
    ----------
    path : str or path-like
        The CSV file, without a header row.

    Returns
    -------
    Experiment
        Input ``V`` [V], output ``y`` [um], ``dt`` from the time column (2e-4 s), name =
        file stem.  50001 samples in the shared file.

    Raises
    ------
    DataError
        Missing file, not 4 comma-separated fields, non-numeric cells, NaN, or a time
        column off its grid by more than 1e-3 of dt.

    Examples
    --------
    >>> from stageid.data.datasets import SHARED_DATA, load_smarthysteresis
    >>> if SHARED_DATA is not None:
    ...     exp = load_smarthysteresis(SHARED_DATA / "piezo_smarthysteresis" / "hysteresis_v_150_1hz.csv")
    ...     assert exp.n_samples == 50001
    """
    p = _existing(path)
    where = f"file '{p.name}': "
    try:
        data = np.loadtxt(p, delimiter=",", usecols=(1, 2, 3), ndmin=2, comments=None)
    except (ValueError, UnicodeDecodeError) as exc:
        raise DataError(
            f"{where}expected 4 comma-separated fields per line (index, time, displacement, voltage): {exc}"
        ) from None
    if data.shape[0] == 0:
        raise DataError(f"file '{p.name}' is empty; expected lines of index, time, displacement, voltage.")
    return _piezo_experiment(data[:, 0], data[:, 2], data[:, 1], None, where, p.stem)


# ============================================================== EMPS (.mat)
_EMPS_UNITS = {"qm": "m", "qg": "m", "vir": "V", "pulses_N": "N"}


def load_emps(path: PathLike) -> Table:
    """Load an EMPS benchmark record (``emps/DATA_EMPS.mat`` or ``emps/DATA_EMPS_PULSES.mat``).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    Table
        Columns ``qm`` (motor position [m]), ``qg`` (reference position [m]), ``vir``
        (controller output [V]; force = 35.15 N/V * vir) and, in the pulse record,
        ``pulses_N`` (external force pulses [N]); ``dt`` from ``t`` (1e-3 s), 24841 samples.
        Direct use: ``table.experiment(["vir"], ["qm"])``; closed loop:
        ``table.experiment(["qg"], ["vir", "qm"])``.  The scalar gains ``gtau``, ``kp``,
        ``kv`` in the file are not columns.

    Raises
    ------
    DataError
        Missing file or variables, unequal lengths, NaN, or time stamps off the grid by
        more than 1e-3 of dt.

    Examples
    --------
    >>> from stageid.data.datasets import SHARED_DATA, load_emps
    >>> if SHARED_DATA is not None:
    ...     table = load_emps(SHARED_DATA / "emps" / "DATA_EMPS.mat")
    ...     assert table.names == ("qm", "qg", "vir")
    """
    p = _existing(path)
    where = f"file '{p.name}': "
    content = _loadmat(p)
    missing = [k for k in ("t", "qm", "qg", "vir") if k not in content]
    if missing:
        raise DataError(f"{where}expected EMPS variables t, qm, qg, vir; missing {', '.join(missing)}.")
    t = _vector(content["t"], "t", where)
    _check_time(t, where)
    names = [k for k in ("qm", "qg", "vir", "pulses_N") if k in content]
    columns = [_vector(content[k], k, where) for k in names]
    for k, col in zip(names, columns):
        if col.size != t.size:
            raise DataError(f"{where}variable '{k}' has {col.size} samples but t has {t.size}; expected one length.")
    t0, dt = time_axis(t, where, None, UNIFORM_RTOL)
    return Table(
        names=tuple(names),
        values=np.column_stack(columns),
        dt=dt,
        t0=t0,
        units=tuple(_EMPS_UNITS[k] for k in names),
        source=p.name,
    )


# ============================================================== DaISy
# canonical name -> (file, dt [s], input names, output names)
_DAISY = {
    "cd_player_arm": ("CD_player_arm.dat", 1.0, ("u1", "u2"), ("y1", "y2")),
    "flexible_structure": (
        "flexibleStructure.mat",
        1.0 / 1024.0,
        ("f1", "f2"),
        tuple(f"a{i}" for i in range(1, 29)),
    ),
    "robot_arm": ("robot_arm.dat", 1.0, ("torque",), ("acceleration",)),
    "ballbeam": ("ballbeam.dat", 0.1, ("angle",), ("position",)),
}
DAISY_SETS: tuple[str, ...] = tuple(_DAISY)


def load_daisy(name: str, root: PathLike | None = None) -> Experiment:
    """Load one of the four mechanical DaISy data sets.

    Parameters
    ----------
    name : {"cd_player_arm", "flexible_structure", "robot_arm", "ballbeam"}
        Case, underscores and the file spelling (``"CD_player_arm"``,
        ``"flexibleStructure"``) are ignored when matching.
    root : str or path-like, optional
        Folder holding the DaISy files; default ``shared_data_dir() / "daisy"``.

    Returns
    -------
    Experiment
        ========================  =====  ============  ========================  ======
        set                       n      inputs        outputs                   dt [s]
        ========================  =====  ============  ========================  ======
        ``cd_player_arm``         2048   u1, u2        y1, y2                    1 (not given)
        ``flexible_structure``    8523   f1, f2        a1 .. a28                 1/1024
        ``robot_arm``             1024   torque        acceleration              1 (not given)
        ``ballbeam``              1000   angle         position                  0.1
        ========================  =====  ============  ========================  ======

    Raises
    ------
    DataError
        Unknown set name, shared data folder not found, missing file, wrong column count
        or NaN values.

    Examples
    --------
    >>> from stageid.data.datasets import SHARED_DATA, load_daisy
    >>> if SHARED_DATA is not None:
    ...     exp = load_daisy("ballbeam")
    ...     assert (exp.n_samples, exp.dt) == (1000, 0.1)
    """
    key = str(name).lower().replace("_", "").replace("-", "")
    matches = [k for k in _DAISY if k.replace("_", "") == key]
    if not matches:
        raise DataError(f"unknown DaISy set '{name}'; expected one of {', '.join(DAISY_SETS)}.")
    canonical = matches[0]
    file_name, dt, ins, outs = _DAISY[canonical]
    if root is None:
        shared = shared_data_dir()
        if shared is None:
            raise DataError(
                f"the shared data folder was not found; set {ENV_VAR} or pass root= (the folder with {file_name})."
            )
        folder = shared / "daisy"
    else:
        folder = Path(root)
    p = _existing(folder / file_name)
    where = f"file '{p.name}': "
    if p.suffix == ".mat":
        content = _loadmat(p)
        if "flexibleStructure" not in content:
            raise DataError(
                f"{where}expected variable 'flexibleStructure'; got {', '.join(k for k in content if not k.startswith('__'))}."
            )
        data = np.asarray(content["flexibleStructure"], dtype=float)
    else:
        try:
            data = np.loadtxt(p, ndmin=2)
        except ValueError as exc:
            raise DataError(f"{where}expected a whitespace-separated numeric matrix: {exc}") from None
    n_cols = len(ins) + len(outs)
    if data.ndim != 2 or data.shape[1] != n_cols:
        raise DataError(
            f"{where}expected {n_cols} columns ({len(ins)} inputs, {len(outs)} outputs); got shape {data.shape}."
        )
    return Experiment(
        u=data[:, : len(ins)],
        y=data[:, len(ins) :],
        dt=dt,
        input_names=ins,
        output_names=outs,
        name=canonical,
    )
