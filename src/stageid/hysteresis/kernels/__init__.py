"""Compiled inner loops of the hysteresis operators (numba, ``cache=True``, ``nogil=True``).

Imported lazily by the operators and models (it imports numba).  Every sum kernel gives the
operator outputs of the plain-Python references :func:`~stageid.hysteresis.operators.play_reference`
and :func:`~stageid.hysteresis.operators.coupled_play_reference` (bit for bit for the loop and
banded kernels, to 1e-12 of the input range for the event kernels); the inversion kernels are
checked by the round trip ``model(inverse(y)) = y``.  Speeds: ``benchmarks/RESULTS-hysteresis.md``.

======================  ==========================================================================
:mod:`.loops`           every operator at every sample: ``play_bank``, ``cp_bank`` (eq. 1, 3),
                        ``play_sum``, ``cp_sum`` (eq. 4); ``gram`` (normal equations),
                        ``cp_rows`` (the least-squares rows and their statistics), ``cp_gram``
                        (the normal equations of those rows, without the rows)
:mod:`.events`          event-driven sums for smooth records: ``play_sum_events``,
                        ``cp_sum_events``, ``count_reversals``, ``lipschitz_state``
:mod:`.banded`          banded sums (only the operator blocks the input can move):
                        ``play_sum_banded``, ``cp_sum_banded``
:mod:`.band_codegen`    the banded sums' LLVM vector code (intrinsics, one emitter per concept)
:mod:`.choice`          ``play_sum_auto``, ``cp_sum_auto``: which sum kernel a record gets
:mod:`.ordering`        ``stable_argsort``, ``quick_argsort``: operators by band width, events by position
:mod:`.inversion`       per-sample inversion (eq. 5): ``cp_invert_step``, ``cp_invert``,
                        ``cp_invert_creep``; the inverse-PI stream ``play_step``, ``play_stream``
:mod:`.filters`         ``unit_gain_columns``: many columns through the stage dynamics at once
                        (bit-equal to ``lfilter``; imported by the stage fit, not re-exported)
======================  ==========================================================================
"""

from .banded import cp_sum_banded, play_sum_banded
from .choice import cp_sum_auto, is_smooth, play_sum_auto, turn_fraction, turns_and_stills
from .events import count_reversals, cp_sum_events, lipschitz_state, play_sum_events
from .inversion import cp_eval, cp_invert, cp_invert_creep, cp_invert_step, play_step, play_stream
from .loops import cp_bank, cp_gram, cp_rows, cp_sum, gram, play_bank, play_sum

__all__ = [
    "play_bank",
    "cp_bank",
    "play_sum",
    "cp_sum",
    "gram",
    "cp_rows",
    "cp_gram",
    "play_sum_events",
    "cp_sum_events",
    "count_reversals",
    "lipschitz_state",
    "play_sum_banded",
    "cp_sum_banded",
    "play_sum_auto",
    "cp_sum_auto",
    "turn_fraction",
    "turns_and_stills",
    "is_smooth",
    "cp_eval",
    "cp_invert_step",
    "cp_invert",
    "cp_invert_creep",
    "play_step",
    "play_stream",
]
