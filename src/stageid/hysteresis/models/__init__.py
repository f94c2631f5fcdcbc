"""The hysteresis models of the modified-PI letter and their building blocks (letter sections 2-3).

====================  ==================================================================
module                what it holds
====================  ==================================================================
:mod:`.operators`     eq. 1-2 play and eq. 3 coupled-play operators, plain-Python references
:mod:`.pi`            eq. 4: ``PIModel`` (classical) and ``ModifiedPIModel``
:mod:`.creep`         ``CreepTerm``: linear creep as first-order lags of the input (our extension)
:mod:`.preisach`      ``PreisachModel`` (uniform cells on a triangular grid), ``everett``
:mod:`.serialization`  the ``stageid.hysteresis/1`` JSON format, ``model_from_dict``,
                      ``register_kind`` (kinds of higher packages load by name)
:mod:`.common`        input and state checks shared by the models, inverses and compensator
====================  ==================================================================

Layers: ``common`` and ``operators`` -> ``creep`` -> ``pi`` -> ``serialization`` (``preisach``
calls its number helpers when it writes itself).  The compiled loops are
:mod:`stageid.hysteresis.kernels`.
"""
