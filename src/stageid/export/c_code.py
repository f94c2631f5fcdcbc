"""``export_c``: a stageid model as a self-contained pair of C99 files.

Which model gives which code:

===========================================  ==============================================
discrete ``StateSpaceModel``/``TransferMatrix``  the simulation recursion (:mod:`.c_lti`)
continuous LTI model + ``dt`` [+ ``method``]       discretised first (``zoh`` as ``stageid
                                                   simulate`` does, or ``tustin``)
``PIModel`` / ``ModifiedPIModel``                  the forward model (:mod:`.c_hysteresis`)
the same with ``inverse=True``                     the streaming compensator (:mod:`.c_inverse`)
``StageModel`` (PI / modified-PI hysteresis)       hysteresis, creep and dynamics (:mod:`.c_stage`)
the same with ``inverse=True``                     its hysteresis compensator, dynamics omitted
===========================================  ==============================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._errors import ModelError
from ..checks import check_choice
from .c_writer import CType, check_prefix, comment, render_pair

__all__ = ["CCode", "export_c", "discretised"]

METHODS = ("zoh", "tustin")


@dataclass(frozen=True)
class CCode:
    """The generated pair: ``header`` (``<prefix>.h``) and ``source`` (``<prefix>.c``)."""

    prefix: str
    header: str
    source: str

    def files(self) -> dict[str, str]:
        """``{"<prefix>.h": header, "<prefix>.c": source}``."""
        return {f"{self.prefix}.h": self.header, f"{self.prefix}.c": self.source}


def _is_lti(model: Any) -> bool:
    from ..models import StateSpaceModel, TransferMatrix

    return isinstance(model, (StateSpaceModel, TransferMatrix))


def _is_hysteresis(model: Any) -> bool:
    from ..hysteresis import ModifiedPIModel, PIModel

    return isinstance(model, (PIModel, ModifiedPIModel))


def discretised(model: Any, dt: float | None, method: str | None) -> Any:
    """The discrete LTI model to export: ``model`` itself, or a continuous one discretised.

    A continuous transfer matrix is discretised through its non-minimal state-space form, the
    one :meth:`~stageid.models.TransferMatrix.simulate` uses.  Raises :class:`ModelError` for a
    continuous model without ``dt``, and for ``dt``/``method`` given with a discrete model whose
    sample time differs.
    """
    from ..models import TransferMatrix, c2d

    if method is not None:
        check_choice(method, "method", "export", METHODS, error=ModelError)
    if model.dt is not None:
        if method is not None or (dt is not None and not np.isclose(dt, model.dt, rtol=1e-9, atol=0.0)):
            raise ModelError(
                f"`dt=`/`method=` discretise a continuous model; this one is discrete with dt = {model.dt!r} s"
                f"{'' if dt is None else f' (got `dt={dt!r}`)'}."
            )
        return model
    if dt is None:
        raise ModelError(
            "the model is continuous (dt = null); give `dt=S` [`method=zoh|tustin`] to discretise it on the way."
        )
    if isinstance(model, TransferMatrix):
        model = model.to_statespace(minimal=False)
    return c2d(model, dt, method or "zoh")


def _is_stage(model: Any) -> bool:
    from ..hysteresis.stage import StageModel

    return isinstance(model, StageModel)


@dataclass(frozen=True)
class _Request:
    """What ``export_c`` was asked for, beside the model."""

    prefix: str
    ctype: CType
    inverse: bool
    dt: float | None
    method: str | None
    limits: tuple[float, float] | None


def _stage_fields(model: Any, r: _Request) -> dict[str, str]:
    from .c_stage import stage_fields, stage_inverse_fields

    if r.method is not None:
        raise ModelError("`method=` discretises a continuous LTI model; a stage model is discrete already.")
    if r.inverse:
        if r.dt is not None:
            raise ModelError("`dt=` applies to the forward model; the compensator of a stage takes no sample time.")
        return stage_inverse_fields(model, r.ctype, r.prefix, r.limits)
    if r.limits is not None:
        raise ModelError("drive limits apply to the compensator (`inverse=True`); got the forward model.")
    return stage_fields(model, r.ctype, r.prefix, r.dt)


def _hysteresis_fields(model: Any, r: _Request) -> dict[str, str]:
    from .c_hysteresis import forward_fields, inverse_fields

    if r.method is not None:
        raise ModelError("`method=` discretises a continuous LTI model; got a hysteresis model.")
    if r.limits is not None and not r.inverse:
        raise ModelError("drive limits apply to the compensator (`inverse=True`); got the forward model.")
    if r.inverse:
        return inverse_fields(model, r.ctype, r.prefix, r.limits)
    if r.dt is not None and model.creep is None:
        raise ModelError("`dt=` sets the creep lags' sample time; this hysteresis model has no creep term.")
    return forward_fields(model, r.ctype, r.prefix, r.dt)


def _model_fields(model: Any, r: _Request) -> dict[str, str]:
    """The template fields of ``model`` from the module that knows its kind (see the table above)."""
    from .c_lti import lti_fields

    if _is_lti(model):
        if r.inverse:
            raise ModelError(
                "`inverse=True` needs a hysteresis model (PI or modified PI); an LTI model has no exported causal inverse."
            )
        if r.limits is not None:
            raise ModelError(
                "drive limits apply to the compensator of a hysteresis model (`inverse=True`); got an LTI model."
            )
        return lti_fields(discretised(model, r.dt, r.method), r.ctype)
    if _is_hysteresis(model):
        return _hysteresis_fields(model, r)
    if _is_stage(model):
        return _stage_fields(model, r)
    raise ModelError(
        f"cannot export a {type(model).__name__} to C; expected a stageid.lti/1 model, a PI / modified-PI "
        "hysteresis model or a stage model."
    )


def export_c(
    model: Any,
    prefix: str,
    *,
    inverse: bool = False,
    single: bool = False,
    dt: float | None = None,
    method: str | None = None,
    limits: tuple[float, float] | None = None,
    source: str = "a model",
) -> CCode:
    """C99 code of ``model``: ``<prefix>.h`` declares ``<prefix>_state``, ``<prefix>_init`` and
    ``<prefix>_step``; ``<prefix>.c`` defines them.

    Parameters
    ----------
    model : StateSpaceModel, TransferMatrix, PIModel, ModifiedPIModel or StageModel
    prefix : str
        C identifier (not a keyword) that starts every exported name.
    inverse : bool, default False
        Export the streaming compensator (desired output -> drive) of a rate-independent
        hysteresis model instead of the model; of a stage model, the compensator of its
        hysteresis (the dynamics are not inverted, :mod:`.c_stage`).
    single : bool, default False
        ``float`` arithmetic instead of ``double``.
    dt : float, optional
        Sample time [s]: discretises a continuous LTI model; the creep lags of a hysteresis
        model run at it (default their ``sample_time``); a stage with dynamics runs at its own.
    method : {"zoh", "tustin"}, optional
        Discretisation of a continuous LTI model (default ``"zoh"``).
    limits : (float, float), optional
        Drive limits of the compensator (default the model's ``input_limits``).
    source : str
        What the header says the code was generated from (e.g. the model file's name).

    Returns
    -------
    CCode

    Raises
    ------
    ParameterError
        A prefix that is not a C identifier or is a C keyword.
    ModelError
        A model kind that cannot be exported, ``inverse`` for a model without an exported causal
        inverse, a continuous model without ``dt``.

    Examples
    --------
    >>> from stageid.hysteresis import PIModel
    >>> code = export_c(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), "act", inverse=True)
    >>> sorted(code.files())
    ['act.c', 'act.h']
    >>> "void act_step(act_state *s, const double *in, double *out);" in code.header
    True
    """
    prefix = check_prefix(prefix)
    ctype = CType("float" if single else "double")
    fields = _model_fields(model, _Request(prefix, ctype, inverse, dt, method, limits))
    fields = {"includes": "", "helpers": "", "constants": "", **fields}
    fields.update(prefix=prefix, ctype=ctype.name, source=comment(source))
    for key in ("input_names", "output_names", "summary", "title"):
        fields[key] = comment(str(fields[key]))
    header, src = render_pair(fields)
    return CCode(prefix, header, src)
