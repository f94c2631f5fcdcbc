"""The joint input-output method: ``r -> u`` and ``r -> y``, then ``G = S_y S_u^-1``.

Ljung, System Identification, 2nd ed., sec. 13.5: with ``u = S_u r + ...`` and
``y = S_y r + ...`` both driven by the recorded references, ``S_y = G S_u`` whatever the
(linear) controller, so ``G = S_y S_u^-1``.  Both maps are open loop (the references are
independent of the noise), each fitted as its own innovation-form model by the predictor-based
subspace method (:mod:`~stageid.closedloop.innovation_fit`, unrefined by default).  One model of
``(u, y)`` together is avoided on purpose: ``u`` is almost a function of ``r`` and ``y``, so
their joint innovation covariance is nearly singular.  The quotient is the series connection of
``S_u^-1 = (A_u - B_u D_u^-1 C_u, B_u D_u^-1, -D_u^-1 C_u, D_u^-1)`` and ``S_y``; the
controller's zeros and the loop's poles ride along as nearly cancelling pairs, and the poles
reported are those of the modes that carry the response (:func:`strong_modes`).  It needs
``D_u`` invertible: a controller that applies the reference a sample late gives ``D_u = 0``,
which ``reference_delay`` undoes by pairing ``r(t - d)`` with ``u(t)`` and ``y(t)``.  A
cross-check of the other routes, without bands.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import IdentificationError
from ..base import Boolean, Interval
from ..data import Experiment
from ..models import StateSpaceModel, series
from ..runtime.threads import single_blas_thread
from .innovation_fit import as_records, fit_innovation, split_references
from .predictor_subspace import InnovationMatrices
from .unknown_checks import excitation_check, reference_share_check, residual_checks
from .unknown_estimator import UnknownControllerEstimator
from .unknown_result import UnknownControllerResult

__all__ = ["JointInputOutput", "quotient", "strong_modes"]


def quotient(S_y: InnovationMatrices, S_u: InnovationMatrices, dt: float) -> StateSpaceModel:
    """``G = S_y S_u^-1`` as the series connection of ``S_u^-1`` and ``S_y`` (deterministic parts).

    Raises
    ------
    IdentificationError
        When ``D_u`` is singular relative to the size of ``S_u`` (no feedthrough from r to u).
    """
    Au, Bu, Cu, Du = S_u.A, S_u.B, S_u.C, S_u.D
    peak = max(
        np.linalg.norm(
            StateSpaceModel(Au, Bu, Cu, Du, dt).frequency_response(np.linspace(0, 0.5 / dt, 64)), 2, axis=(1, 2)
        )
    )
    smallest = np.linalg.svd(Du, compute_uv=False).min()
    if smallest < 1e-3 * peak:
        raise IdentificationError(
            f"references -> plant inputs has no direct feedthrough (smallest gain {smallest:.2g} of peak {peak:.2g}); "
            "the controller acts late: set `reference_delay` to its delay in samples."
        )
    Di = np.linalg.inv(Du)
    inv = StateSpaceModel(Au - Bu @ Di @ Cu, Bu @ Di, -Di @ Cu, Di, dt)
    return series(inv, StateSpaceModel(S_y.A, S_y.B, S_y.C, S_y.D, dt))


def strong_modes(G: StateSpaceModel, tol: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """The poles of ``G`` and a mask of those whose mode carries at least ``tol`` of the response's peak.

    The peak contribution of mode ``k`` on the unit circle is ``|C v_k| |w_k B| / dist(z_k, |z| = 1)``;
    the controller's zeros that ``S_u^-1`` brings in as nearly cancelled pairs fall below it.
    """
    z, V = np.linalg.eig(G.A)
    W = np.linalg.inv(V)
    dist = np.maximum(np.abs(np.abs(z) - 1.0), 1e-12)
    weight = np.linalg.norm(G.C @ V, axis=0) * np.linalg.norm(W @ G.B, axis=1) / dist
    return z, weight >= tol * weight.max()


class JointInputOutput(UnknownControllerEstimator):
    """Identify a plant by the joint input-output method, ``G = S_y S_u^-1`` (a cross-check; no bands).

    Parameters
    ----------
    order, order_range, horizon, max_nfev :
        As for :class:`~stageid.closedloop.direct.DirectPredictionError`, for each of ``r -> u`` and
        ``r -> y`` (their order is the loop's, plant plus controller states, plus the noise's).
    feedthrough : bool
        Whether ``r -> y`` feeds through (a plant with ``D``); ``r -> u`` always does.
    references : list of str
        Input columns of the records that are the references (required).
    reference_delay : int
        Samples by which the controller acts late (pairs ``r(t - d)`` with ``u(t)``, ``y(t)``).
    refine : bool
        Refine both subspace estimates by prediction error (default False: the PBSID estimates,
        consistent for this open-loop problem, in a second instead of minutes at the loop's order).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> from stageid.plants import levitated_pair as lp
    >>> r, u, y = lp.record(4000, seed=0)
    >>> exp = Experiment(np.hstack([r, u]), y, lp.DT, ("r1", "r2", "u1", "u2"))
    >>> res = JointInputOutput(order=8, references=["r1", "r2"]).fit(exp)
    >>> [round(float(p.real)) for p in res.unstable_poles]              # true: 31.4, 50
    [31, 50]
    """

    method_name = "joint"

    def __init__(
        self,
        *,
        order: int | str = "auto",
        order_range: Sequence[int] = tuple(range(1, 13)),
        horizon: int | str = "auto",
        feedthrough: bool = False,
        max_nfev: int = 100,
        references: Sequence[str] | None = None,
        reference_delay: int = 0,
        refine: bool = False,
    ) -> None:
        super().__init__(
            order=order, order_range=order_range, horizon=horizon, feedthrough=feedthrough, max_nfev=max_nfev,
            references=references,
        )  # fmt: skip
        self.reference_delay = reference_delay
        self.refine = refine

    parameter_constraints = {
        **UnknownControllerEstimator.parameter_constraints,
        "reference_delay": [Interval(int, 0, None)],
        "refine": [Boolean()],
    }

    @single_blas_thread
    def fit(self, data: Experiment | Sequence[Experiment]) -> UnknownControllerResult:
        """Fit ``r -> (u, y)`` and form ``G = S_y S_u^-1``.

        Parameters
        ----------
        data : Experiment or sequence of Experiment
            Inputs: the references (named in ``references``) and the plant inputs; outputs: ``y``.

        Returns
        -------
        UnknownControllerResult
            ``innovation`` and ``pole_std`` are None (no bands).

        Raises
        ------
        ParameterError
            A bad setting.
        DataError
            No references named, unknown names, records that disagree.
        IdentificationError
            No feedthrough from the references to the plant inputs, or a failed fit.
        """
        self.validate_params()
        exps = as_records(data)
        r, u, u_names = split_references(exps, self.references, True, type(self).__name__)
        assert r is not None
        d = int(self.reference_delay)
        rs = [x[: x.shape[0] - d] for x in r]
        us, ys = [x[d:] for x in u], [e.y[d:] for e in exps]
        args = (self.order, self.order_range, self.horizon)
        fit_u = fit_innovation(rs, us, *args, True, self.max_nfev, refine_start=self.refine)
        fit_y = fit_innovation(rs, ys, *args, self.feedthrough, self.max_nfev, refine_start=self.refine)
        dt = exps[0].dt
        G = quotient(fit_y.matrices, fit_u.matrices, dt).with_names(u_names, exps[0].output_names)
        lam = fit_u.matrices.noise_cov.diagonal()
        share = float(np.min(1.0 - lam / np.vstack([x - x.mean(axis=0) for x in us]).var(axis=0)))
        checks = [
            reference_share_check(max(share, 0.0)),
            excitation_check(min(fit_u.rcond, fit_y.rcond)),
            *residual_checks(fit_y.residuals, [x[fit_y.burn :] for x in rs], False),
        ]
        z, strong = strong_modes(G)
        s = np.log(z[strong].astype(complex)) / dt
        details = {
            "reference_share": share,
            "weak_modes_left_out": int(np.sum(~strong)),
            "orders": {"r->u": fit_u.order, "r->y": fit_y.order},
        }
        poles = s[np.argsort(s.real, kind="stable")]
        return self.route_result(G, poles, (G.n_states, max(fit_u.horizon, fit_y.horizon)), checks, details)
