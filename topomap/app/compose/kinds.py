"""The kinds of component a run is made of, declared once.

Every list of kinds in the app is :data:`KINDS` or derived from it: the kinds a plugin's
:class:`~topomap.app.compose.hookspecs.Component` may have, the config groups of the top-level config
(:class:`topomap.app.compose.schemas.Config`), the components of a run and the order they are built in
(:class:`topomap.app.compose.registry.Parts`), the :class:`~topomap.MapLearner` arguments they fill (and
the config keys the learner's errors are reported under), and the plugins behind the learner's
components in ``metrics.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

__all__ = ["Kind", "KINDS", "parts_of"]


@dataclass(frozen=True)
class Kind:
    """One kind of component.

    Attributes
    ----------
    name : str
        The kind's name: ``Component.kind``, the config group that selects the component
        (``topomap split=<name>``) and the attribute of :class:`~topomap.app.compose.registry.Parts`
        holding the built object.
    returns : str
        What the component's factory returns (the interface the app relies on).
    simulated : bool
        A part of the simulated world: built only when the data component simulates.
    learner_arg : str or None
        The :class:`~topomap.MapLearner` argument the built object is passed as.
    part_of : str or None
        A part of the component of that kind (a world's sensor): built before it and passed to
        its factory as the argument named after this kind, which is then no field of that
        component's config.  Its group selects nothing by default (``null``: the factory's own
        default applies); a component whose factory takes no such argument refuses one.
    """

    name: str
    returns: str
    simulated: bool = False
    learner_arg: str | None = None
    part_of: str | None = None


#: every kind, by name, in the order the app builds them -- but for ``data``, built first of all
#: (it tells whether the world is built)
KINDS = MappingProxyType({kind.name: kind for kind in (
    Kind("sensor", "``sense(arena, motion) -> (T, D)`` observations along a whole path "
                   "(:mod:`topomap.worlds.arena.sensors`)", simulated=True, part_of="env"),
    Kind("actions", "``action_names``; ``actions(motion) -> (T,)`` action ids read off a path "
                    "(:mod:`topomap.worlds.arena.actions`)", simulated=True, part_of="env"),
    Kind("odometry", "``dead_reckoning(motion, rng) -> (T, 3)``: the robot's own x, y, heading "
                     "along a path (:mod:`topomap.worlds.arena.odometry`)", simulated=True,
         part_of="env"),
    Kind("env", "a world: ``simulate(n_steps, explorer, rng) -> Trajectory`` (optional: "
                "``plot_room(ax)``, ``heldout_walk(n_steps, explorer, rng, after)``, an "
                "``extra_actions=`` argument, the parts it takes: ``sensor=``, ``actions=``)",
         simulated=True),
    Kind("noise", "``apply(observations, rng) -> observations`` (a new array)", simulated=True),
    Kind("explorer", "``choose(executable_mask, rng) -> action id``", simulated=True),
    Kind("metric", "``fit_transform(X) -> Z``; K-means runs on ``Z``", learner_arg="metric"),
    Kind("clusters", "``choose(Z, random_state) -> ns``", learner_arg="clusters"),
    Kind("split", "``propose(counts) -> (side, score) | None``", learner_arg="split"),
    Kind("stop", "``check(n_initial)``; ``should_stop(n_states, best_score)``",
         learner_arg="stop"),
    Kind("refine", "``fit(sequence, split_state_symbol, random_state)`` returning itself with "
                   "``labels_``, ``state_symbol_`` (and ``info_``) set "
                   "(:mod:`topomap.core.refine.methods`; a ``CloneFit`` returned instead is "
                   "accepted until 0.4), or None for none", learner_arg="refine"),
    Kind("data", "``simulates`` (bool); ``train(parts, seed, progress)`` and "
                 "``heldout(parts, seed)`` return Trajectory objects (or None)"),
    Kind("evaluate", "``evaluate(map, labels, places, world, noise) -> dict``, or None for no "
                     "extra evaluation"),
    Kind("logger", "``log_run(record)`` with a :class:`~topomap.app.components.loggers.RunRecord` once the "
                   "run has written its outputs, or None for no logging"),
)})


def parts_of(kind: str) -> tuple[str, ...]:
    """The kinds that are parts of a component of ``kind`` (a world's ``sensor`` and ``actions``):
    its factory is given them built, so they are no fields of its config."""
    return tuple(name for name, k in KINDS.items() if k.part_of == kind)
