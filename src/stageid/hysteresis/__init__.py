"""Hysteresis: play and coupled-play operators, classical and modified PI models, inverse, compensation.

Implements the modified Prandtl-Ishlinskii letter (``shared/papers``): eq. 1-2 (play),
eq. 3 (coupled play, consistent reading documented in :mod:`.operators`), eq. 4 (modified PI),
eq. 5 (inverse) and the feedforward scheme of Fig. 9.

==========================  ==================================================================
``OperatorState``           last input and operator outputs (resume a model where it stopped)
``play``                    bank of play operators (eq. 1-2)
``coupled_play``            bank of coupled-play operators (eq. 3)
``PIModel``                 classical PI: weighted plays plus a linear term
``ModifiedPIModel``         modified PI of eq. 4
``CreepTerm``               optional linear creep of either model (first-order lags of the input)
``PIIdentifier``            thresholds equally spaced, constrained LS weights, CP thresholds by
                            nonlinear optimisation; ``fit`` returns ``HysteresisResult``
``pi_inverse``              closed-form inverse of a classical PI model (a PI model)
``invert``                  per-sample monotone inversion of any (modified) PI model
``Compensator``             streaming feedforward compensator with state and drive limits
``compensate``              batch feedforward
``StageModel``              rate-dependent stage: hysteresis -> creep -> unit-DC-gain dynamics
``StageIdentifier``         joint identification of a stage; ``fit`` returns ``StageResult``
``stage_feedforward``       offline inverse of a stage (stable inversion of the dynamics)
``PreisachModel``           discrete Preisach model: uniform-density cells on a triangular grid
``PreisachIdentifier``      NNLS weights with a smoothness penalty; ``fit`` returns ``PreisachResult``
``PreisachCompensator``     exact Preisach inverse, streaming, with memory and drive limits
``preisach_feedforward``    exact Preisach inverse, batch
``everett``                 Everett function of a Preisach model (``everett_output``: the output
                            as Everett differences over the memory)
``max_error_percent``       metrics as the letter uses them (see :mod:`.metrics`)
``rms_error_percent``
``tracking_error_percent``
``hysteresis_percent``
==========================  ==================================================================

Every estimator's ``fit`` takes the data as one argument (an Experiment, a sequence of them,
or (u, y) pairs); ``HysteresisFit``, ``PreisachFit`` and ``StageFit`` are the former names of
the results.

Sub-packages and modules, from the letter's sections down (each imports only the ones below it):

===============================  ==================================================================
:mod:`.stage`                    the rate-dependent stage (our extension): ``StageModel``,
                                 ``StageIdentifier`` (hysteresis, then weights / creep / dynamics
                                 alternated), its dynamics, disturbance modes, order and creep
                                 evidence, validation and offline feedforward
:mod:`.identify`                 identification, one module per step of the letter: ``PIIdentifier``
                                 (thresholds, weights, CP thresholds, starting states, creep),
                                 weight covariance, ``PreisachIdentifier``
:mod:`.inverse`                  eq. 5 and Fig. 9: ``invert`` (per sample), the classical PI's
                                 closed form, the compensators, the exact Preisach inverse
:mod:`.models`                   eq. 1-4: play and coupled-play operators, ``PIModel``,
                                 ``ModifiedPIModel``, ``CreepTerm``, ``PreisachModel``, and the
                                 ``stageid.hysteresis/1`` JSON format (``serialization``)
:mod:`.kernels`                  the compiled loops (numba), imported on first use
:mod:`.metrics`                  the letter's error and hysteresis measures
===============================  ==================================================================

The flat module paths of earlier versions (``stageid.hysteresis.stage_problem``,
``stageid.hysteresis.pi``, ...) still import, as the modules at their new places
(:mod:`stageid._moved`).
"""

from .identify.pi import HysteresisFit, HysteresisResult, PIIdentifier, align_record
from .identify.preisach import PreisachFit, PreisachIdentifier, PreisachResult
from .inverse import invert, pi_inverse
from .inverse.compensator import Compensator, compensate
from .inverse.preisach import PreisachCompensator, preisach_feedforward
from .metrics import hysteresis_percent, max_error_percent, rms_error_percent, tracking_error_percent
from .models.creep import CreepTerm
from .models.operators import OperatorState, coupled_play, play
from .models.pi import ModifiedPIModel, PIModel
from .models.preisach import PreisachModel, everett, everett_output
from .stage import StageModel
from .stage.identification import StageFit, StageIdentifier, StageResult
from .stage.inverse import stage_feedforward

__all__ = [
    "OperatorState",
    "play",
    "coupled_play",
    "PIModel",
    "ModifiedPIModel",
    "CreepTerm",
    "PIIdentifier",
    "HysteresisResult",
    "HysteresisFit",
    "align_record",
    "pi_inverse",
    "invert",
    "Compensator",
    "compensate",
    "StageModel",
    "StageIdentifier",
    "StageResult",
    "StageFit",
    "stage_feedforward",
    "PreisachModel",
    "PreisachIdentifier",
    "PreisachResult",
    "PreisachFit",
    "PreisachCompensator",
    "preisach_feedforward",
    "everett",
    "everett_output",
    "max_error_percent",
    "rms_error_percent",
    "tracking_error_percent",
    "hysteresis_percent",
]
