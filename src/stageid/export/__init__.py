"""Export of stageid models for real-time targets: C99 code and MATLAB files.

=================  =====================================================================
``export_c``       a model as ``<prefix>.h`` / ``<prefix>.c`` (C99, no heap, no I/O):
                   discrete LTI recursion, PI / modified-PI forward model, or the
                   streaming compensator of a rate-independent hysteresis model
``CCode``          the generated pair (``.files()``: name -> text)
``export_mat``     a model as a v5 MAT file: ``A, B, C, D, Ts`` and channel names as
                   MATLAB's ``ss()`` takes them, or a struct of hysteresis parameters
``check_prefix``   the rule for C prefixes (an identifier that is not a C keyword)
=================  =====================================================================

===========================  ===========================================================
module                       what it holds
===========================  ===========================================================
:mod:`.c_code`               ``export_c``: which model kind goes to which module below
:mod:`.c_writer`             exact constants, identifiers, the two-file template, fills
:mod:`.c_lti`                discrete LTI models: the simulation recursion
:mod:`.c_hysteresis`         PI / modified-PI forward models (with creep), compensator entry
:mod:`.c_pi_inverse`         the classical PI compensator: its closed-form inverse
:mod:`.c_inverse`            the modified-PI compensator: per-sample inversion (Newton,
                             safeguards)
:mod:`.c_reversal_curve`     its first iterate after a turn: the reversal curve's root
:mod:`.c_float_sums`         its single-precision passes: compensated sums
:mod:`.c_creep_inverse`      the classical PI compensator with its creep term
:mod:`.c_stage`              stage models: hysteresis, creep and dynamics in one step
:mod:`.host`                 compiling and running exported code on this machine (tests)
:mod:`.matlab`               ``export_mat``: MAT files of LTI, hysteresis and stage models
===========================  ===========================================================
"""

from .c_code import CCode, export_c
from .c_writer import check_prefix
from .matlab import export_mat

__all__ = ["CCode", "export_c", "export_mat", "check_prefix"]
