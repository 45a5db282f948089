"""A new action for topomap's office world: "turn back" to the place the robot came from.

Installed, it is found through the entry point group ``topomap``; without installing, list it in
the config: ``topomap 'plugins=[topomap_turnback]'`` (the module must be importable) or give the
file path: ``topomap 'plugins=[path/to/topomap_turnback.py]'``.
"""

from topomap import hookimpl
from topomap.worlds.office import Action, GoTo


class TurnBack(Action):
    """Drive back to the standing point of the previous place.

    Executable whenever the robot has a previous place different from the current one.  Like every
    office action it stops early within reach of another object, or when it turned too much.
    """

    name = "turn back"

    def is_executable(self, world, pose):
        return pose.prev_place >= 0 and pose.prev_place != pose.place

    def execute(self, world, pose, rng):
        target = world.standing_point(pose.prev_place)
        return world.drive(pose, [GoTo(target)])


@hookimpl
def topomap_world_actions(world, params):
    if world == "office":
        return [TurnBack()]
    return []
