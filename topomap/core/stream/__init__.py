"""Fitting logs larger than memory: the paper's two phases on a folder or list of logs read in
chunks, on this process or on the workers of a Ray cluster.

==============  ==============================================================================
module          its one job
==============  ==============================================================================
``fit``         the streamed fit (:meth:`topomap.MapLearner.fit_stream`)
``plan``        the survey of the logs and their names made consistent
``phase1``      K-means on gathered rows, every step's symbol, the phase-1 states and models
``jobs``        the work on one log, wherever it runs
``moments``     observation means and scatter gathered chunk by chunk
``engines``     where the per-log work runs: this process or Ray
``learner``     the learner's ``fit_stream`` method
==============  ==============================================================================
"""
