"""Layer 7, simulation: a whole run over the trajectory.

:mod:`.checks` (the input checks that need the geometry, before any tracing),
:mod:`.runner` (one scenario point by point: chains, adversary, detectors, outcome),
:mod:`.executors` (where the chains run: here, forked processes, Dask), :mod:`.run_folder`
(``run.json``, resume, versions, keys), :mod:`.engine` (:func:`~.engine.run`, the main job)
and :mod:`.montecarlo` (realisations, mean and confidence intervals); :mod:`.blas` (one BLAS
thread in a Dask worker) and :mod:`.process_cluster` (a Dask cluster of separate processes).
"""
