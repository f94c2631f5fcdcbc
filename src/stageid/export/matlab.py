"""``export_mat``: a stageid model as a MATLAB v5 MAT file (:func:`scipy.io.savemat`).

LTI models (state space, or a transfer matrix through its state-space realisation) are stored
as the arguments of MATLAB's ``ss``::

    m = load('M.mat');
    sys = ss(m.A, m.B, m.C, m.D, m.Ts, 'InputName', m.InputName, 'OutputName', m.OutputName);

``Ts`` is the sample time in seconds, ``0`` for a continuous model (MATLAB's convention);
``InputName``/``OutputName`` are cell arrays of char, one name per channel.  A transfer matrix
also carries ``num`` and ``den``, cell arrays of row vectors as MATLAB's ``tf`` takes them.

A PI or modified-PI model is stored as one struct ``hysteresis`` holding every field of its
``stageid.hysteresis/1`` JSON form (vectors as columns, ``null`` as ``[]``, the operator state
and a creep term as nested structs), plus ``InputName``/``OutputName``.

A stage model (:class:`~stageid.hysteresis.stage.StageModel`) keeps its parts apart: the
struct ``hysteresis`` as above, its dynamics as ``A, B, C, D, Ts`` (``ss()``'s arguments) and
as ``num``, ``den``, the row vectors in powers of ``z^-1`` its simulation filters with (MATLAB:
``tf(m.num, m.den, m.Ts, 'Variable', 'z^-1')``), a struct ``creep`` when the stage holds the
creep term (Preisach hysteresis), ``disturbance_modes`` (rows of frequency [Hz], damping) when
recorded, and ``kind = 'stage'``.  A stage without dynamics has no ``A ... den``.
"""

from __future__ import annotations

import os
from typing import IO, Any

import numpy as np

from .._errors import ModelError

__all__ = ["export_mat", "mat_variables", "stage_variables"]


def _names(names: Any) -> np.ndarray:
    cell = np.empty((len(names), 1), dtype=object)
    for i, n in enumerate(names):
        cell[i, 0] = str(n)
    return cell


def _matlab_value(value: Any) -> Any:
    """A JSON value as savemat stores it: lists of numbers as columns, None as [], dicts as structs."""
    if value is None:
        return np.zeros((0, 0))
    if isinstance(value, dict):
        return {k: _matlab_value(v) for k, v in value.items()}
    if isinstance(value, list):
        if all(isinstance(v, str) for v in value):
            return _names(value)
        return np.asarray(value, dtype=float).reshape(-1, 1)
    if isinstance(value, bool):
        return bool(value)
    if isinstance(value, (int, float)):
        return float(value)
    return value


def _polynomials(model: Any, key: str) -> np.ndarray:
    rows = getattr(model, key)
    cell = np.empty((model.n_outputs, model.n_inputs), dtype=object)
    for i in range(model.n_outputs):
        for j in range(model.n_inputs):
            cell[i, j] = np.asarray(rows[i][j], dtype=float).reshape(1, -1)
    return cell


def mat_variables(model: Any, dt: float | None = None, method: str | None = None) -> dict[str, Any]:
    """The variables of the MAT file (name -> value), see the module notes.

    ``dt``/``method`` discretise a continuous LTI model first (as :func:`export_c`); without
    them a continuous model is stored with ``Ts = 0``.

    Examples
    --------
    >>> from stageid.models import StateSpaceModel
    >>> v = mat_variables(StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.01))
    >>> sorted(v), v["Ts"]
    (['A', 'B', 'C', 'D', 'InputName', 'OutputName', 'Ts'], 0.01)
    """
    from ..hysteresis import ModifiedPIModel, PIModel
    from ..hysteresis.stage import StageModel
    from ..models import StateSpaceModel, TransferMatrix
    from .c_code import discretised

    if isinstance(model, (StateSpaceModel, TransferMatrix)):
        if dt is not None or method is not None:
            model = discretised(model, dt, method)
        ss = model if isinstance(model, StateSpaceModel) else model.to_statespace()
        n, m, p = ss.n_states, ss.n_inputs, ss.n_outputs
        out: dict[str, Any] = {
            "A": np.asarray(ss.A, dtype=float).reshape(n, n),
            "B": np.asarray(ss.B, dtype=float).reshape(n, m),
            "C": np.asarray(ss.C, dtype=float).reshape(p, n),
            "D": np.asarray(ss.D, dtype=float).reshape(p, m),
        }
        out["Ts"] = 0.0 if model.dt is None else float(model.dt)
        if isinstance(model, TransferMatrix):
            out["num"], out["den"] = _polynomials(model, "num"), _polynomials(model, "den")
    elif isinstance(model, StageModel):
        if method is not None or dt is not None:
            raise ModelError("`dt=`/`method=` discretise a continuous LTI model; a stage model is discrete already.")
        out = stage_variables(model)
    elif isinstance(model, (PIModel, ModifiedPIModel)):
        if method is not None or dt is not None:
            raise ModelError("`dt=`/`method=` discretise a continuous LTI model; got a hysteresis model.")
        out = {"hysteresis": _matlab_value(model.to_dict())}
    else:
        raise ModelError(
            f"cannot export a {type(model).__name__} to MATLAB; expected a stageid.lti/1 model, a PI / "
            "modified-PI hysteresis model or a stage model."
        )
    out["InputName"], out["OutputName"] = _names(model.inputs), _names(model.outputs)
    return out


def stage_variables(model: Any) -> dict[str, Any]:
    """The MAT variables of a stage model's parts (module notes), channel names aside."""
    out: dict[str, Any] = {"kind": "stage", "hysteresis": _matlab_value(model.hysteresis.to_dict())}
    g = model.dynamics
    if g is not None:
        n = g.n_states
        out["A"], out["B"] = np.asarray(g.A, dtype=float).reshape(n, n), np.asarray(g.B, dtype=float).reshape(n, 1)
        out["C"], out["D"] = np.asarray(g.C, dtype=float).reshape(1, n), np.asarray(g.D, dtype=float).reshape(1, 1)
        out["Ts"] = float(g.dt)
        b, a = model.transfer()
        out["num"], out["den"] = np.asarray(b, dtype=float).reshape(1, -1), np.asarray(a, dtype=float).reshape(1, -1)
    if model.creep is not None:
        out["creep"] = _matlab_value(model.creep.to_dict())
    if model.disturbance_modes:
        out["disturbance_modes"] = np.asarray(model.disturbance_modes, dtype=float).reshape(-1, 2)
    return out


def export_mat(
    model: Any, file: str | os.PathLike[str] | IO[bytes], dt: float | None = None, method: str | None = None
) -> None:
    """Write :func:`mat_variables` of ``model`` to ``file`` as a MATLAB v5 MAT file.

    Raises :class:`ModelError` for a model kind that cannot be exported.
    """
    from scipy.io import savemat

    savemat(file, mat_variables(model, dt, method), format="5", oned_as="column", do_compression=False)
