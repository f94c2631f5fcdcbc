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

Modules: :mod:`.c_writer` (exact constants, identifiers, the file template), :mod:`.c_lti`,
:mod:`.c_hysteresis` and :mod:`.c_inverse` (code per model kind), :mod:`.c_code` (dispatch),
:mod:`.matlab`.
"""

from .c_code import CCode, export_c
from .c_writer import check_prefix
from .matlab import export_mat

__all__ = ["CCode", "export_c", "export_mat", "check_prefix"]
