"""The hysteresis models of the modified-PI letter and their building blocks (letter sections 2-3).

====================  ==================================================================
module                what it holds
====================  ==================================================================
:mod:`.operators`     eq. 1-2 play and eq. 3 coupled-play operators, plain-Python references
:mod:`.pi_base`       what every PI model shares: operator bank, state, run, file fields
:mod:`.pi`            eq. 1: ``PIModel`` (classical; ``ModifiedPIModel`` re-exported)
:mod:`.modified_pi`   eq. 4: ``ModifiedPIModel`` (coupled-play operators, input warp)
:mod:`.creep`         ``CreepTerm``: linear creep as first-order lags of the input (our extension)
:mod:`.preisach`      ``PreisachModel`` (uniform cells on a triangular grid), ``everett``
:mod:`.serialization`  the ``stageid.hysteresis/1`` JSON format, ``model_from_dict``,
                      ``register_kind`` (kinds of higher packages load by name)
:mod:`.common`        input and state checks shared by the models, inverses and compensator;
                      the packed operator parameters and the rounding bound of the computed
                      output (``residual_bound``) that the inversion kernels take
====================  ==================================================================

Layers: ``common`` -> ``operators`` -> ``creep`` -> ``pi_base`` -> ``modified_pi`` -> ``pi`` ->
``serialization`` (``preisach``
calls its number helpers when it writes itself).  The compiled loops are
:mod:`stageid.hysteresis.kernels`.
"""
