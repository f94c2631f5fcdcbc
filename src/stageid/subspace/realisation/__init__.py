"""From the eq. 9 estimate to a state-space model (Cao & Chen 2013, sections 2.1-2.2, eq. 10-15).

===========================  ================================================================
module                       what it holds
===========================  ================================================================
:mod:`.era`                  H0 (eq. 10), H_i (eq. 12), H(0)/H(1) (eq. 14), Lemma 1 (eq. 15,
                             ``era``); ``realize`` picks the route by name (``REALIZATIONS``)
:mod:`.frequency_domain`     the frequency route: that response over the excited band,
                             realised (frequency counterpart of Lemma 1), two starts
:mod:`.route`                ``RouteTask``: what every route is given
:mod:`.refinement`           output-error refinement of a realisation on that response
:mod:`.output_error`         the realised model refined on the records' simulated output
                             error (time domain, modal form)
:mod:`.weighting`            noise weighting of the outputs in the realisation and selection
                             (``weighted_parts``: theta and its covariance in those outputs)
===========================  ================================================================
"""
