"""Simulate a robot in the arena, record its log as ROS bags, learn a map from the bags.

The robot of ``topomap experiment=arena_robot``: ratinabox's random motion with a small robot's
speeds (:data:`ROBOT_MOTION`) in two alike furnished rooms off a corridor (the arena's
``alike_rooms``), a 60-beam range finder fixed to the robot (``sensor.frame=egocentric``: beam 0
straight ahead, with N(0, 0.02^2) m noise), turn / forward / stop commands read off its motion
(``actions=turns``) and its wheel odometry (``odometry=wheel``,
:class:`~topomap.worlds.arena.WheelOdometry`: 2 % speed noise, 5 % turn-rate noise, a gyro bias of
0.01 rad/s at most, slips of up to 0.03 m and rad), integrated from the robot's own start pose.

Each bag holds what a robot records, one message per topic at every step (10 Hz): ``/scan``
(``sensor_msgs/LaserScan``), ``/cmd_vel`` (``geometry_msgs/Twist``), ``/odom``
(``nav_msgs/Odometry``, drifting), ``/tf`` (``odom`` -> ``base_link``) and the simulator's truth
on ``/truth`` (``geometry_msgs/PoseStamped`` in ``map``), which only scores the map.  Usage (needs
``pip install "topomap[arena,ros]"``)::

    python docs/examples/robot_bag.py robot.bag              # ROS 1: robot.bag, robot_heldout.bag
    python docs/examples/robot_bag.py robot --version 2 --steps 6000 --heldout-steps 2000

The script reads the bags back (``read_rosbag(..., odometry_topic="/odom",
position_topic="/truth")``), learns a map from the first, scores it in metres on the second
beside the yardsticks of ``metrics.json`` (the ceiling, K-means on the views), says how far the
odometry drifted, and prints the ``topomap`` command that does the same from the bags.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from topomap import MapLearner, Trajectory, read_rosbag, write_rosbag
from topomap.evaluation.metres import learner_scores
from topomap.worlds.arena import ArenaWorld, Motion, RangeFinder, TurnActions, WheelOdometry

#: metres of N(0, s^2) noise on every range reading
SCAN_NOISE = 0.02
#: ratinabox's random motion with a small robot's speeds (m/s, s, rad/s, s, -, m), as
#: ``conf/experiment/arena_robot.yaml``'s ``env``
ROBOT_MOTION = dict(speed_mean=0.1, speed_coherence_time=1.0, rotational_velocity_std=1.0,
                    rotational_velocity_coherence_time=0.5, thigmotaxis=0.2,
                    wall_repel_distance=0.1)
#: metres and radians a wheel slip adds at most (the preset's ``odometry.slip_size``)
SLIP_SIZE = 0.03


def true_odometry(positions: np.ndarray, dt: float) -> np.ndarray:
    """``(T - 1, 3)``: the true path seen from the robot's start pose, as an odometry without
    errors would read it (what the wheel odometry drifts from)."""
    exact = WheelOdometry(speed_noise=0, turn_noise=0, gyro_bias=0, slip_rate=0, slip_size=0)
    return exact.dead_reckoning(Motion.from_samples(positions, dt), np.random.default_rng(0))


def robot_log(world: ArenaWorld, steps: int, rng: np.random.Generator) -> Trajectory:
    """``steps`` steps of the robot: noisy scans, commands, the truth and the wheel odometry."""
    traj = world.simulate(steps, None, rng)
    scans = traj.observations + SCAN_NOISE * rng.standard_normal(traj.observations.shape)
    return Trajectory(np.clip(scans, 0.0, None), traj.actions, positions=traj.positions,
                      action_names=traj.action_names, odometry=traj.odometry)


def parse_args(argv=None) -> argparse.Namespace:
    """The command-line arguments."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", type=Path, help="the training bag: a .bag file (ROS 1) or a "
                                               "folder (ROS 2); the held-out bag goes beside it")
    parser.add_argument("--steps", type=int, default=18000, help="training steps (10 Hz)")
    parser.add_argument("--heldout-steps", type=int, default=6000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--version", type=int, choices=[1, 2], default=1)
    parser.add_argument("--clusters", type=int, default=32)
    parser.add_argument("--states", type=int, default=64)
    return parser.parse_args(argv)


def write_bags(args) -> tuple[Path, Path, ArenaWorld]:
    """Simulate the two walks and write them as bags; returns their paths and the world."""
    world = ArenaWorld("alike_rooms", sensor=RangeFinder(n_beams=60, frame="egocentric"),
                       actions=TurnActions(), odometry=WheelOdometry(slip_size=SLIP_SIZE),
                       **ROBOT_MOTION)
    rng_train, rng_held = (np.random.default_rng(s)
                           for s in np.random.SeedSequence(args.seed).spawn(2))
    held = args.out.with_name(args.out.stem + "_heldout" + args.out.suffix)
    topics = dict(version=args.version, action_topic=None, cmd_vel_topic="/cmd_vel",
                  position_topic="/truth")
    write_rosbag(robot_log(world, args.steps, rng_train), args.out, **topics)
    write_rosbag(robot_log(world, args.heldout_steps, rng_held), held, **topics)
    return args.out, held, world


def main(argv=None) -> dict:
    """Write the bags, learn from them, print the scores and the command; returns the scores."""
    args = parse_args(argv)
    train_bag, held_bag, world = write_bags(args)
    topics = dict(action_names=world.action_names, odometry_topic="/odom",
                  position_topic="/truth")
    train = read_rosbag(train_bag, "/scan", "/cmd_vel", **topics)
    heldout = read_rosbag(held_bag, "/scan", "/cmd_vel", **topics)
    print(f"wrote {train_bag} ({len(train)} steps) and {held_bag} ({len(heldout)} steps): "
          "/scan, /cmd_vel, /odom, /tf, /truth")
    truth = true_odometry(train.positions, world.dt)
    drift = np.hypot(*(train.odometry[len(truth) - 1, :2] - truth[-1, :2]))
    print(f"the odometry drifted {drift:.2f} m from the truth over {len(train) * world.dt:.0f} s")
    learner = MapLearner(n_clusters=args.clusters, n_states=args.states, random_state=0)
    learner.fit_trajectory(train)
    scores = learner_scores(learner, train, heldout, world.region_of)
    for name, s in scores.items():
        print(f"{name:>12}: median error {s['median_error']:.3f} m, "
              f"wrong region {s['wrong_region']:.1%}")
    print(f"the same from the command line: topomap data=rosbag data.path={train_bag} "
          f"data.heldout_path={held_bag} data.observation_topic=/scan "
          f"data.action_topic=/cmd_vel data.odometry_topic=/odom data.position_topic=/truth "
          f"'data.action_names=[{','.join(world.action_names)}]' clusters.ns={args.clusters} "
          f"stop.n_states={args.states}")
    return scores


if __name__ == "__main__":
    main()
