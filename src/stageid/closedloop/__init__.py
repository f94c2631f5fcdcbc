"""Closed-loop identification of open-loop-unstable MIMO plants with a known controller
(Shakir & Kim, Int. J. Control Autom. Syst., 2010).

==============================  ============================================================
``ClosedLoopIdentification``    configure-then-fit estimator of the whole method (Fig. 2)
``ClosedLoopResult``            its frozen result: plant, closed loop, poles, eps, diagnostics
``pem``                         prediction-error fit of eq. 12-14 (ARX, ARMAX, OE, BJ)
``arx``                         least-squares ARX, the linear start of the fits
``select_order``                order selection by BIC/AIC
``PolynomialModel``             A y = B/F u(t-nk) + C/D e (eq. 12)
``excited_reference``           the one reference an experiment excites
``deduce_plant``                eq. 18 as a state-space model, G = T (M - M T)^-1
``deduce_response``             eq. 18 frequency by frequency (singularity checked)
``deduce_siso``                 SISO eq. 18 in polynomials with the paper's spurious factors
``unstable_plant_poles``        zeros of M (I - T) outside the unit circle
``cancel_entries``              spurious pole-zero pairs per entry, with distances (3.2.3)
``reduce_entry``                fixed-structure continuous fit over a band (3.3)
``simulate_closed_loop``        sampled loop with output noise at a given SNR
``empirical_transfer``          FFT ratio Y / R of one experiment
``reclose_loop``                identified plant closed with the known controller (Fig. 8)
``direct_identification``       the biased open-loop baseline from u to y
==============================  ============================================================

Without a controller model (``direct``, ``two_stage``, ``joint``; shared steps in
``predictor_subspace``, ``innovation_pem`` with its Jacobian ``innovation_jacobian``,
``innovation_fit``, ``unknown_checks``):

==============================  ============================================================
``DirectPredictionError``       prediction error on measured u and y, innovation form
``TwoStageProjection``          r -> u, then the plant from the simulated u
``JointInputOutput``            r -> (u, y), then G = S_y S_u^-1 (a cross-check, no bands)
``UnknownControllerResult``     their frozen result: plant, poles with bands, assumptions, checks
``unstable_pole_agreement``     do the routes agree on the unstable poles?
``simulate_feedback``           a sampled loop with saturation and a feedback delay
==============================  ============================================================

Modules, in the order of the method (Fig. 2):

==============================  ============================================================
``loop_model``                  the pairs of ``T`` from the experiments (eq. 11-17)
``prefilter``                   the diagonal pairs again through the outputs' sensitivity noise model
``polynomial``                  the model structures (ARX, ARMAX, OE, BJ; eq. 12)
``regression``                  lagged regressors and least squares
``initial``                     ARX / Steiglitz-McBride / Hannan-Rissanen starts
``pem``                         the prediction-error fit (eq. 13-14)
``reduced_lsq``                 SciPy's least squares on the QR-reduced problem
``covariance``                  the PEM parameters' covariance (eq. 13-14)
``order_selection``             BIC / AIC over a climb in order
``mode_injection``              a lightly damped mode where a residual follows the input
``controller``                  the known controller, discrete at the data's sample time, checked
``deduction``                   eq. 18 (state space, frequency by frequency, SISO polynomials)
``reliability``                 eq. 18's first-order error gain, weighing the reduction's lines
``cancellation``                spurious pole-zero pairs (sec. 3.2.3)
``zoh``                         the ZOH equivalent of a continuous entry and its derivatives
``reduction``                   fixed-structure fit of one entry over a band (sec. 3.3)
``plant_reduction``             every entry, or the full order kept
``uncertainty``                 the PEM covariance carried through eq. 18 and the reduction
``estimator``, ``result``       the whole method and its frozen result
``validation``                  simulation, the re-closed loop, the direct baseline
``feedback_simulation``         sampled loops with saturation and a feedback delay
==============================  ============================================================

The routes without a controller model: ``unknown_estimator`` (their common base),
``unknown_result`` (their result), ``unknown_checks`` (the assumptions they check),
``direct``, ``two_stage``, ``joint``, and their shared steps ``predictor_subspace``,
``innovation_pem``, ``innovation_jacobian``, ``innovation_fit``.
"""

from .cancellation import CancelledPair, EntryPoleZero, cancel_entries, cancel_pairs
from .deduction import deduce_plant, deduce_response, deduce_siso, unstable_plant_poles
from .direct import DirectPredictionError
from .estimator import ClosedLoopIdentification
from .feedback_simulation import simulate_feedback
from .initial import arx
from .joint import JointInputOutput
from .loop_model import excited_reference
from .order_selection import select_order
from .pem import pem
from .polynomial import PolynomialModel
from .reduction import ReducedEntry, paper_orders, reduce_entry
from .result import ClosedLoopResult
from .two_stage import TwoStageProjection
from .unknown_result import UnknownControllerResult, unstable_pole_agreement
from .validation import (
    controller_residual,
    direct_identification,
    empirical_transfer,
    reclose_loop,
    simulate_closed_loop,
)

__all__ = [
    "ClosedLoopIdentification",
    "ClosedLoopResult",
    "excited_reference",
    "pem",
    "arx",
    "select_order",
    "PolynomialModel",
    "deduce_plant",
    "deduce_response",
    "deduce_siso",
    "unstable_plant_poles",
    "cancel_entries",
    "cancel_pairs",
    "CancelledPair",
    "EntryPoleZero",
    "reduce_entry",
    "ReducedEntry",
    "paper_orders",
    "simulate_closed_loop",
    "empirical_transfer",
    "reclose_loop",
    "direct_identification",
    "controller_residual",
    "DirectPredictionError",
    "TwoStageProjection",
    "JointInputOutput",
    "UnknownControllerResult",
    "unstable_pole_agreement",
    "simulate_feedback",
]
