"""Compare learned states with ground-truth places (the functions of
:mod:`topomap.evaluation.partitions`, under the name users import them by).

Every function takes ``(labels_true, labels_pred)``, in scikit-learn's order: the true place of
every step first, then the learned state of every step.  ARI and NMI are symmetric, but purity
and the count of compound states are not::

    purity(labels_true=places, labels_pred=learner.labels_)
"""

from .evaluation.partitions import adjusted_rand, compound_states, evaluate, nmi, purity

__all__ = ["adjusted_rand", "nmi", "purity", "compound_states", "evaluate"]
