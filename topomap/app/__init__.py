"""The ``topomap`` command (floor 3): Hydra configs, plugins, runs and sweeps.

Its rooms, each importing only those listed after it:

* :mod:`topomap.app.cli` -- the entry point: the command line, then one run or a sweep;
* :mod:`topomap.app.run` -- doing one run: its data, the learner, the evaluation, its files;
* :mod:`topomap.app.compose` -- what a run is made of: kinds, plugins, typed configs, checks;
* :mod:`topomap.app.components` -- the app's own components: data sources and loggers;
* :mod:`topomap.app.report` -- reading runs back: a sweep's jobs, its summary and report;
* :mod:`topomap.app.plots` -- the figures of a run, in the style the sweep's figure shares;
* :mod:`topomap.app.results` -- what a run leaves: its files and the numbers in them.
"""
