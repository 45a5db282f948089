"""How good a learned map is, outside the learner: every score a run reports.

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``partitions``      learned states against ground-truth places: ARI, NMI, purity, compound
                    states (public as :mod:`topomap.metrics`)
``metres``          learned states against true positions, in metres: the map, the ceiling
                    (the true places in topomap's model class) and K-means on the views
==================  ===========================================================================

It stands above the learning core and imports from it the clustering and the counts the
learner uses too (:func:`~topomap.core.phase1.clustering.view_clusters`,
:func:`~topomap.core.stats.label_means`, :func:`~topomap.core.stats.majority_share`); the core
never imports it.
"""
