"""Research routes for robot logs on the package's robot route (:mod:`topomap.core.motion.robot`,
``MapLearner(motion="robot")``): a metric map from headings closed by loops, then an HMM over
(cell, heading) whose transitions carry the odometric displacement (``bench_robots.py --routes
headgraph_kf headgraph_kf_teleport headgraph_kf_scans``).

``headgraph_kf``          with wheel odometry (rung 2): :func:`~topomap.core.motion.robot.
                          learn_robot` and :func:`~topomap.core.motion.robot.place_walk` as
                          they are, the cells and places seeded by the bench seed
``headgraph_kf_teleport`` the same, a teleport anywhere allowed at ``TELEPORT``
``headgraph_kf_scans``    without (rung 3): turns from the scans, each moving command one unit
                          of travel unless stopped (:func:`~topomap.core.motion.reckoning.
                          command_poses`; the log holds no speed; the unit is the same in both
                          walks)
``headgraph_kf_icp``      without (rung 3): odometry from the scans registered against
                          keyframes (:func:`~topomap.core.motion.registration.scan_odometry`) in
                          both walks, its turns calibrated against the scans' as a wheel
                          odometry's
``headgraph_kf_slam``     the same, the training walk's positions closed by loops too
                          (:func:`~topomap.core.motion.registration.scan_poses`)

Each held-out step is scored at the mean training position of its place (one of ``n_states``
K-means places on the estimated positions).
"""

from __future__ import annotations

from topomap.core.motion.reckoning import command_poses
from topomap.core.motion.registration import scan_odometry, scan_poses
from topomap.core.motion.robot import JUMP, learn_robot, place_walk
from topomap.evaluation.metres import score_units

ROUTES = ("headgraph_kf", "headgraph_kf_teleport", "headgraph_kf_scans", "headgraph_kf_icp",
          "headgraph_kf_slam")
#: a teleport's probability a keyframe in ``headgraph_kf_teleport``: a held-out stay of
#: thousands of steps in one of two identical rooms then drifts to the room trained on more
#: steps (its cells are denser, its scans fit a few nats a step better)
TELEPORT = 1e-4


def route(name, tw, hw, regions, seed, n_clusters, n_states):
    train, held = tw.traj, hw.traj
    scans = name == "headgraph_kf_scans"
    odo = command_poses(train.observations, train.actions) if scans else tw.odometry
    held_odo = command_poses(held.observations, held.actions) if scans else hw.odometry
    if name in ("headgraph_kf_icp", "headgraph_kf_slam"):
        odo, held_odo = scan_odometry(train.observations), scan_odometry(held.observations)
    if name == "headgraph_kf_slam":
        odo = scan_poses(train.observations)
    model, places, _ = learn_robot(train.observations, odo, n_states, seed,
                                   odometry_turns=not scans)
    held_places, _ = place_walk(model, held.observations, held_odo,
                                TELEPORT if name == "headgraph_kf_teleport" else JUMP)
    pair = (regions(train.positions), regions(held.positions))
    return {"states": model.n_cells, **score_units(places, train.positions, held_places,
                                                   held.positions, n_states, pair)}
