"""How the library runs, not what it computes: compiled kernels, threads, memory, clusters.

Every package below may import these; they import nothing of stageid but the errors.

=====================  ===================================================================
module                 what it holds
=====================  ===================================================================
:mod:`.simd`           4-wide vector intrinsics that every numba kernel is written in
:mod:`.unroll`         one mechanism to write a kernel's short loops out (``written_out``)
:mod:`.numba_cache`    where compiled kernels are cached (a read-only install still runs)
:mod:`.threads`        ``single_blas_thread``: one BLAS thread inside the fits;
                       ``map_in_threads``: independent work on several threads
:mod:`.heap`           ``prime_heap``: malloc's thresholds raised once per process
:mod:`.lazy`           ``lazy_names``: a package's names imported on first use (PEP 562)
:mod:`.resources`      ``require_memory`` / ``require_work``: guards before large work
:mod:`.cluster`        ``dask_client``: a Dask cluster for batches and larger-than-memory
                       records, with one-line errors for an unreachable scheduler
=====================  ===================================================================

The old paths (``stageid.simd``, ``stageid.resources``, ``stageid.cluster``,
``stageid.numba_cache``, ``stageid._threads``, ``stageid._heap``,
``stageid.subspace.unroll``) still import these modules (:mod:`stageid._moved`).
"""
