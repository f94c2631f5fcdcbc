"""The direct prediction-error method on closed-loop data: the plant from measured ``u`` and ``y`` alone.

Ljung, System Identification, 2nd ed., sec. 13.4: fit ``y = G u + H e`` to the records as if
they were open loop.  The estimate is consistent in closed loop when the model set holds the
true ``G`` *and* ``H`` and the loop has a delay, whatever the controller (linear or not,
known or not); a too-rigid noise model biases ``G`` in proportion to the noise the controller
feeds back.  Here ``G`` and ``H`` share the innovation form ``x(t+1) = A x + B u + K e``,
``y = C x + D u + e``, whose predictor ``A - K C`` is stable even for an unstable ``A``.

Steps of :meth:`DirectPredictionError.fit`: the past horizon by the VARX predictor's BIC, the
order by the BIC of the PBSID start (:mod:`~stageid.closedloop.predictor_subspace`), the
prediction-error refinement and its covariance (:mod:`~stageid.closedloop.innovation_pem`),
then the checks (:mod:`~stageid.closedloop.unknown_checks`).
"""

from __future__ import annotations

from collections.abc import Sequence

from ..data import Experiment
from ..runtime.threads import single_blas_thread
from .innovation_fit import as_records, fit_innovation, split_references
from .unknown_checks import (
    excitation_check,
    noise_feedback_check,
    reference_share_check,
    residual_checks,
    share_explained,
)
from .unknown_estimator import UnknownControllerEstimator
from .unknown_result import UnknownControllerResult

__all__ = ["DirectPredictionError"]


class DirectPredictionError(UnknownControllerEstimator):
    """Identify a (possibly unstable) MIMO plant from closed-loop ``u`` and ``y``, controller unknown.

    Parameters
    ----------
    order : "auto" or int
        States of the innovation form (plant and noise share them); "auto": BIC over ``order_range``.
    order_range : sequence of int
        Candidate orders for "auto".
    horizon : "auto" or int
        Past horizon of the subspace start (VARX order); "auto": BIC over 5-40 samples.
    feedthrough : bool
        Fit ``D`` (only when the controller surely acts one sample late; the default strictly
        proper plant needs no delay in the controller).
    max_nfev : int
        Evaluation limit of the prediction-error optimisation.
    references : list of str, optional
        Input columns of the records that are references (not plant inputs); they only feed
        the ``reference_share`` check.

    Examples
    --------
    >>> from stageid.data import Experiment
    >>> from stageid.plants import levitated_pair as lp
    >>> r, u, y = lp.record(4000, seed=0)
    >>> res = DirectPredictionError(order=4).fit(Experiment(u, y, lp.DT))
    >>> [round(float(p.real)) for p in res.unstable_poles]              # true: 31.4, 50
    [31, 50]
    """

    method_name = "direct"

    @single_blas_thread
    def fit(self, data: Experiment | Sequence[Experiment]) -> UnknownControllerResult:
        """Fit the innovation form to the records' plant inputs and outputs.

        Parameters
        ----------
        data : Experiment or sequence of Experiment
            Inputs: the plant inputs ``u`` as logged (and any reference columns named in
            ``references``); outputs: the measured ``y``.

        Returns
        -------
        UnknownControllerResult

        Raises
        ------
        ParameterError
            A bad setting.
        DataError
            Not experiments, records that disagree, unknown reference names.
        IdentificationError
            Records too short for the horizon, or no stable predictor at any order.
        """
        self.validate_params()
        exps = as_records(data)
        r, u, u_names = split_references(exps, self.references, False, type(self).__name__)
        y = [e.y for e in exps]
        fit = fit_innovation(u, y, self.order, self.order_range, self.horizon, self.feedthrough, self.max_nfev)
        u_used = [x[fit.burn :] for x in u]
        checks = [excitation_check(fit.rcond), *residual_checks(fit.residuals, u_used, self.feedthrough)]
        checks.append(noise_feedback_check(fit.residuals, u_used))
        if r is not None:
            checks.append(reference_share_check(max(0.0, share_explained(u, r, range(0, fit.horizon)))))
        return self.plant_result(fit, exps[0].dt, (u_names, exps[0].output_names), checks)
