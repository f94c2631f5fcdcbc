"""The two-stage (projection) method: the plant from the part of ``u`` the references explain.

Van den Hof & Schrama, Automatica 29, 1993 (two-stage); Forssell & Ljung, Automatica 36, 2000
(projection): stage 1 fits the sensitivity ``r -> u``, an open-loop problem because the
references are independent of the noise; its noise-free simulation ``u^ = S_u r`` is then
uncorrelated with the noise too, so stage 2 fits the plant ``u^ -> y`` as an open-loop problem
with any noise model.  Nothing is assumed about the controller but linearity of ``r -> u``;
the price is variance: only the reference-driven part of ``u`` informs the plant.

Both stages are innovation-form fits (:mod:`~stageid.closedloop.innovation_fit`); stage 2 keeps
the innovation form so that an unstable plant still has a stable predictor.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import IdentificationError
from ..data import Experiment
from ..models import StateSpaceModel
from ..runtime.threads import single_blas_thread
from .innovation_fit import as_records, fit_innovation, split_references
from .unknown_checks import excitation_check, reference_share_check, residual_checks
from .unknown_estimator import UnknownControllerEstimator
from .unknown_result import UnknownControllerResult

__all__ = ["TwoStageProjection", "simulate_sensitivity"]


def simulate_sensitivity(r: Sequence[np.ndarray], u: Sequence[np.ndarray], order, order_range, max_nfev: int):
    """Stage 1: fit ``r -> u`` (with feedthrough) and return ``(u^ per record, order, share explained)``.

    The subspace estimate is kept as it is: the problem is open loop, where PBSID is consistent,
    and only the simulated ``u^`` is used.
    """
    fit = fit_innovation(r, u, order, order_range, "auto", True, max_nfev, refine_start=False)
    m = fit.matrices
    S = StateSpaceModel(m.A, m.B, m.C, m.D, dt=1.0)
    if not S.is_stable():
        raise IdentificationError(
            "stage 1 (references -> plant inputs) came out unstable; the loop is stable, so try another "
            "`sensitivity_order`."
        )
    u_hat = [S.simulate(x - x.mean(axis=0)) for x in r]
    res = np.vstack([x - x.mean(axis=0) - h for x, h in zip(u, u_hat)])
    total = np.vstack([x - x.mean(axis=0) for x in u])
    share = float(np.min(1.0 - res.var(axis=0) / total.var(axis=0)))
    return u_hat, fit.order, share


class TwoStageProjection(UnknownControllerEstimator):
    """Identify a (possibly unstable) MIMO plant by the two-stage method; the controller is not used.

    Parameters
    ----------
    order, order_range, horizon, feedthrough, max_nfev :
        As for :class:`~stageid.closedloop.direct.DirectPredictionError`, for stage 2 (the plant).
    references : list of str
        Input columns of the records that are the references (required).
    sensitivity_order : "auto" or int
        States of the stage-1 model ``r -> u``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> from stageid.plants import levitated_pair as lp
    >>> r, u, y = lp.record(4000, seed=0)
    >>> exp = Experiment(np.hstack([r, u]), y, lp.DT, ("r1", "r2", "u1", "u2"))
    >>> res = TwoStageProjection(order=4, sensitivity_order=8, references=["r1", "r2"]).fit(exp)
    >>> [round(float(p.real)) for p in res.unstable_poles]              # true: 31.4, 50
    [32, 50]
    """

    method_name = "two-stage"

    def __init__(
        self,
        *,
        order: int | str = "auto",
        order_range: Sequence[int] = tuple(range(1, 13)),
        horizon: int | str = "auto",
        feedthrough: bool = False,
        max_nfev: int = 100,
        references: Sequence[str] | None = None,
        sensitivity_order: int | str = "auto",
    ) -> None:
        super().__init__(
            order=order, order_range=order_range, horizon=horizon, feedthrough=feedthrough, max_nfev=max_nfev,
            references=references,
        )  # fmt: skip
        self.sensitivity_order = sensitivity_order

    parameter_constraints = {
        **UnknownControllerEstimator.parameter_constraints,
        "sensitivity_order": UnknownControllerEstimator.parameter_constraints["order"],
    }

    @single_blas_thread
    def fit(self, data: Experiment | Sequence[Experiment]) -> UnknownControllerResult:
        """Stage 1 ``r -> u``, then stage 2 ``u^ -> y``.

        Parameters
        ----------
        data : Experiment or sequence of Experiment
            Inputs: the references (named in ``references``) and the plant inputs; outputs: ``y``.

        Returns
        -------
        UnknownControllerResult

        Raises
        ------
        ParameterError
            A bad setting.
        DataError
            No references named, unknown names, records that disagree.
        IdentificationError
            An unstable stage-1 model, or a failed stage-2 fit.
        """
        self.validate_params()
        exps = as_records(data)
        r, u, u_names = split_references(exps, self.references, True, type(self).__name__)
        assert r is not None
        u_hat, n1, share = simulate_sensitivity(r, u, self.sensitivity_order, self.order_range, self.max_nfev)
        y = [e.y for e in exps]
        fit = fit_innovation(u_hat, y, self.order, self.order_range, self.horizon, self.feedthrough, self.max_nfev)
        used = [x[fit.burn :] for x in u_hat]
        checks = [
            reference_share_check(share),
            excitation_check(fit.rcond),
            *residual_checks(fit.residuals, used, self.feedthrough),
        ]
        return self.plant_result(
            fit, exps[0].dt, (u_names, exps[0].output_names), checks, sensitivity_order=n1, reference_share=share
        )
