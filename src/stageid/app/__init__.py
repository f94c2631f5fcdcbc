"""``stageid serve``: the identification boards of MATLAB's System Identification app, in a local web page.

=====================  ===================================================================
``server``             the ASGI application: routes, session cookie, token, error replies
``sessions``           one private workspace per browser session; safe record/upload names
``jobs``               fits and exports off the request thread, in a child process, cancellable
``records``            data board: read, pick channels, trim, detrend, time plot and spectrum
``estimate``           estimate board: FRF, Hankel-MAP, FRD fit, hysteresis, singular values
``compare``            compare board (``stageid validate``) and export board (JSON, C, MAT)
=====================  ===================================================================

Needs the ``app`` extra (Starlette, uvicorn): ``pip install stageid[app]``.
"""
