"""What closed-loop data can check about the assumptions of the routes without a controller model.

Every route states its assumptions (:data:`ASSUMPTIONS`); each :class:`Check` tests one thing
the records can show:

* ``excitation``: the reciprocal condition number of the past-data covariance (persistence of
  excitation at the predictor's horizon); near zero, the records cannot separate the models;
* ``whiteness``: the one-step residual of each output is white (Ljung-Box); a coloured residual
  means the noise model is too rigid, which is exactly when the direct method is biased;
* ``past_inputs``: the residual is uncorrelated with past inputs ``u(t-1), u(t-2), ...``;
* ``same_sample_feedback`` (informative, without a fitted feedthrough): the correlation of ``u(t)``
  with the residual ``e(t)`` at the same sample, nonzero when the controller acts within the
  sample (no delay in the feedback); a fitted ``D`` removes it by construction, so then the
  records cannot tell;
* ``noise_feedback``: the share of the input's power that past residuals explain, i.e. noise
  fed back by the controller; the direct method's bias from a wrong noise model scales with it
  (Ljung, System Identification, 2nd ed., eq. 13.38);
* ``reference_share``: the share of the input's power the references explain (the two-stage and
  joint routes have nothing else to work with).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..validation import independence_test, whiteness_test

__all__ = [
    "Check",
    "ASSUMPTIONS",
    "excitation_check",
    "residual_checks",
    "noise_feedback_check",
    "reference_share_check",
    "share_explained",
]

ASSUMPTIONS = {
    "direct": (
        "the noise model (the innovation form's K and Lambda, of the plant's order) can describe the disturbances; "
        "if not, the plant estimate is biased in proportion to the noise fed back by the controller",
        "the loop holds at least one sample of delay (the plant is strictly proper unless feedthrough is fitted; "
        "a fitted feedthrough needs a controller that surely acts a sample late, which the records cannot show)",
        "the controller may be unknown, nonlinear or saturating; only u and y are used",
        "the excitation (references, noise, controller switching) keeps the past of u and y persistently exciting",
    ),
    "two-stage": (
        "the references are recorded and independent of the noise",
        "stage 1: the map r -> u is linear and of the given order (saturation or a nonlinear controller "
        "leaves a part of u unexplained, treated as noise)",
        "stage 2: the plant is fitted from the simulated noise-free u; its noise model is free",
        "the plant's uncertainty bands ignore the uncertainty of stage 1",
    ),
    "joint": (
        "the references are recorded and independent of the noise",
        "r -> (u, y) is one linear system; G = S_y S_u^-1 needs S_u invertible (direct feedthrough from r to u "
        "after `reference_delay` samples)",
        "a cross-check of the other routes: no bands",
    ),
}


@dataclass(frozen=True)
class Check:
    """One check of an assumption: the value measured, its limit, the verdict and what it means.

    An ``informative`` entry is a measurement to read, not a test (it always "passes").
    """

    name: str
    passed: bool
    value: float
    limit: float
    meaning: str
    informative: bool = False

    def line(self) -> str:
        """One line for summaries."""
        verdict = "info" if self.informative else "ok" if self.passed else "FAILED"
        return f"{self.name}: {verdict} ({self.value:.3g}, limit {self.limit:.3g}) - {self.meaning}"


def excitation_check(rcond: float, limit: float = 1e-10) -> Check:
    """Persistence of excitation from the reciprocal condition number of the past-data covariance."""
    return Check(
        "excitation",
        rcond > limit,
        rcond,
        limit,
        "reciprocal condition number of the covariance of the past inputs and outputs",
    )


def residual_checks(
    residuals: Sequence[np.ndarray], inputs: Sequence[np.ndarray], feedthrough: bool, max_lag: int = 25
) -> list[Check]:
    """Whiteness, independence from past inputs, and the same-sample feedback (see the module notes)."""
    p, m = residuals[0].shape[1], inputs[0].shape[1]
    white = [whiteness_test([e[:, i] for e in residuals], max_lag) for i in range(p)]
    worst_w = max(t.statistic / t.threshold for t in white)
    past = [
        independence_test([e[1:, i] for e in residuals], [u[:-1, j] for u in inputs], max_lag)
        for i in range(p)
        for j in range(m)
    ]
    worst_p = max(t.statistic / t.threshold for t in past)
    same = np.array(
        [abs(_corr0([e[:, i] for e in residuals], [u[:, j] for u in inputs])) for i in range(p) for j in range(m)]
    )
    bound = 2.58 / np.sqrt(sum(e.shape[0] for e in residuals))  # 1 % two-sided
    checks = [
        Check(
            "whiteness", worst_w <= 1.0, worst_w, 1.0, "largest Ljung-Box statistic / its 1 % threshold over outputs"
        ),
        Check(
            "past_inputs",
            worst_p <= 1.0,
            worst_p,
            1.0,
            "largest residual-vs-past-input chi-square / its 1 % threshold over output-input pairs",
        ),
    ]
    if not feedthrough:  # a fitted D removes this correlation by construction: nothing left to measure
        checks.append(
            Check(
                "same_sample_feedback",
                True,
                float(same.max()),
                float(bound),
                "largest |corr(u(t), e(t))|, informative: above the limit the controller acts within the sample "
                "(fine for a strictly proper plant; do not fit feedthrough then)",
                informative=True,
            )
        )
    return checks


def _corr0(es: Sequence[np.ndarray], us: Sequence[np.ndarray]) -> float:
    e = np.concatenate([x - x.mean() for x in es])
    u = np.concatenate([x - x.mean() for x in us])
    d = np.sqrt((e @ e) * (u @ u))
    return float(e @ u / d) if d > 0 else 0.0


def share_explained(target: Sequence[np.ndarray], regressors: Sequence[np.ndarray], lags: range) -> float:
    """Smallest over channels of ``1 - var(res) / var(target)`` of ``target(t)`` on ``regressors(t - k)``, k in lags."""
    rows, ys = [], []
    k0, k1 = lags.start, lags.stop - 1
    for x, y in zip(regressors, target):
        n = y.shape[0]
        rows.append(np.hstack([x[k1 - k : n - k] for k in range(k0, k1 + 1)]))
        ys.append(y[k1:])
    Phi, Y = np.vstack(rows), np.vstack(ys)
    Y = Y - Y.mean(axis=0)
    theta = np.linalg.lstsq(Phi - Phi.mean(axis=0), Y, rcond=None)[0]
    res = Y - (Phi - Phi.mean(axis=0)) @ theta
    return float(np.min(1.0 - res.var(axis=0) / np.maximum(Y.var(axis=0), 1e-300)))


def noise_feedback_check(residuals: Sequence[np.ndarray], inputs: Sequence[np.ndarray], lags: int = 20) -> Check:
    """Share of the input's power explained by past residuals (noise fed back); informative, never failed."""
    share = max(0.0, share_explained(inputs, residuals, range(1, lags + 1)))
    return Check(
        "noise_feedback",
        True,
        share,
        1.0,
        "share of the input power explained by past residuals; the direct method's bias from a wrong noise "
        "model grows with it",
        informative=True,
    )


def reference_share_check(share: float, limit: float = 0.05) -> Check:
    """The references must explain a part of the input's power for the two-stage and joint routes."""
    return Check(
        "reference_share",
        share >= limit,
        share,
        limit,
        "share of the input power the references explain (stage 1, r -> u)",
    )
