"""The refinement after the split: EM over clones of the symbols, and structure moves.

``methods`` -- the refinements :class:`topomap.MapLearner` takes, one object per method
(``EMRefinement``, ``CSCGRefinement``), each reading top-down from its ``fit``;
``clones`` -- the clone-structured HMM they fit (layout, Baum-Welch, Viterbi training);
``structure`` -- merging bisimilar states and splitting compound ones; ``kernels`` -- the compiled
clone EM; ``convergence`` -- when an iterative fit stops.
"""
