"""The refinement after the split: EM over clones of the symbols, and structure moves.

``methods`` -- the refinements :class:`topomap.MapLearner` takes, one estimator per method
(``EMRefinement``, ``CSCGRefinement``), each reading top-down from its ``fit``, which sequences
hard and soft rounds; ``sequence`` -- their input, the steps as symbol ids; ``clones`` -- the
clone-structured HMM they fit (layout, Baum-Welch, Viterbi training); ``budget`` -- the clones
the first EM stage gets; ``structure`` -- merging bisimilar states and splitting compound ones;
``settings`` -- the settings, one small object per stage (``hard``, ``growth``, ``soft``,
``reading``); ``soft`` -- the soft round (misread symbols as evidence); ``evidence`` -- what
every soft round runs, whatever its evidence; ``observed`` -- evidence from each step's own
observation; ``confusion`` -- the confusion matrix; ``provenance`` -- the text map.json keeps
of a refinement; ``renamed`` -- the settings' names before 0.3; ``resize`` -- bringing a refined
map to the told number of states; ``kernels``, ``soft_kernels`` -- the compiled clone EM;
``convergence`` -- when an iterative fit stops.
"""
