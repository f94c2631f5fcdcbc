"""The ``stageid`` command line: the only part of stageid that prints or exits.

One module per verb, imported only when its command runs or a help text lists it:

================================  ================================================================
``main``                          the ``stageid`` group, its lazy command table, errors to exit 2
``identify_statespace``           ``identify statespace``: Hankel-Toeplitz MAP (Cao & Chen)
``identify_closedloop``           ``identify closed-loop``: known controller (Shakir & Kim)
``identify_closedloop_unknown``   ``identify closedloop --controller unknown``
``identify_frd``                  ``identify frd``: a state-space fit to a frequency response
``identify_hysteresis``           ``identify hysteresis``: PI, modified PI, Preisach, stage
``frf``, ``bla``                  ``frf``: a measured frequency response; ``--method bla``
``validate``                      ``validate``: fit, RMS error and residual tests
``lti``                           ``simulate`` and ``freqresp``
``compensate``                    ``compensate``: feedforward from a hysteresis model
``signal``, ``multisine_files``   ``signal KIND``: excitation signals and a multisine's files
``plants``                        ``plants NAME``: the reference stages
``export``                        ``export c`` and ``export mat``
``report``, ``demo``, ``serve``   HTML reports, the demo, the browser boards
``batch``                         ``batch``: a manifest of command lines on a Dask cluster
================================  ================================================================

Shared by the verbs:

================================  ================================================================
``_common``                       name lists, bands, reading records, ``--start``/``--stop``,
                                  messages printed after success, the command line for reports
``outputs``                       ``-o`` files and report folders: checked first, written atomically
``progress``                      progress on stderr (a bar on a terminal, lines in a log)
``flags``                         library messages' ``name=`` as ``--flag``
``chunked_input``                 chunked records (HDF5, Zarr, ``.npy``) and ``--scheduler``
``uncertainty``                   ``--uncertainty``, shared by the ``identify`` verbs
================================  ================================================================
"""
