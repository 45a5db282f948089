"""Robots as they log, simulated: egocentric LiDAR, turn / forward / stop commands, wheel odometry.

A reusable harness (``benchmarks/bench_robots.py`` and ``benchmarks/bench_robot_cost.py`` run
it): a differential-drive robot moves at random in a floor plan (ratinabox's
``Agent`` with a robot's speeds), senses a ring of range beams fixed to its body (beam 0 straight
ahead), is commanded ``forward`` / ``turn_left`` / ``turn_right`` / ``stop`` (the arena's
``actions=turns``, the ROS ``Twist`` rule) and keeps its own dead reckoning (wheel odometry
simulated from the truth with noise, a gyro bias and slips).  A walk is a :class:`RobotWalk`:
the :class:`~topomap.Trajectory` (observations, actions, true positions), the true heading and
the odometry, an (T, 3) array x [m], y [m], heading [rad] in the robot's own frame.

Every walk is cached as an npz (``--cache``); the same (plan, seed, robot) gives the same walk.

Floor plans: ``robot_twin``, ``robot_alike``, ``robot_three``, ``robot_office`` (``benchmarks/floorplans/``, at a
robot's scale) and the arena's layouts and rat floor plans scaled by :data:`RAT_TO_ROBOT` (1 m
rooms become 2.5 m rooms, 0.3 m doors 0.75 m doors).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from topomap import Trajectory
from walk_stamp import walk_stamp

HERE = Path(__file__).resolve().parent
#: the robot floor plans (metres as they stand)
ROBOT_PLANS = ("robot_twin", "robot_alike", "robot_three", "robot_office")
#: the arena's and the rat floor plans, scaled to a robot
RAT_PLANS = ("two_rooms", "four_rooms", "corridor", "open", "alcoves", "l_rooms", "pillars",
             "three_rooms", "grid6", "ring", "sizes")
#: the factor the rat floor plans are scaled by: their 0.3 m doors become 0.75 m, wide enough
#: for a robot that keeps 0.3 m from walls
RAT_TO_ROBOT = 2.5
#: the plans every figure of the robot routes was developed on; the others are held out
DEVELOP = ("robot_twin", "two_rooms")


@dataclass(frozen=True)
class Robot:
    """A differential-drive robot: ratinabox's random motion with a robot's speeds, a LiDAR in
    its own frame, the command rule and its wheel odometry's errors."""

    speed_mean: float = 0.2            # m/s
    speed_coherence_time: float = 1.0  # s
    turn_std: float = 1.0              # rad/s, sd of the turning rate
    turn_coherence_time: float = 0.5   # s
    thigmotaxis: float = 0.2
    wall_repel_distance: float = 0.3   # m: the robot's radius and a margin
    dt: float = 0.1                    # s: 10 Hz
    beams: int = 60
    max_range: float = 3.5             # m
    range_sigma: float = 0.02          # m, Gaussian range noise
    dropout: float = 0.01              # share of beams that read max_range (no return)
    angular_threshold: float = 0.5     # rad/s: a turn command (the arena's TurnActions)
    speed_noise: float = 0.02          # relative, per step and as a per-walk calibration error
    turn_noise: float = 0.05           # relative, per step and as a per-walk calibration error
    gyro_bias: float = 0.01            # rad/s: the largest bias; drawn in [bias / 2, bias]
    slip_rate: float = 0.01            # slips per second
    slip_size: float = 0.1             # m and rad: the largest error a slip adds

    @classmethod
    def small(cls, **changes) -> "Robot":
        """A robot at a rat's scale (1 m rooms, 0.3 m doors): slower, closer to walls."""
        return cls(**{"speed_mean": 0.1, "wall_repel_distance": 0.1, "slip_size": 0.03,
                      **changes})

    def name(self) -> str:
        base = Robot()
        diff = [f"{k}={getattr(self, k)}" for k in self.__dataclass_fields__
                if getattr(self, k) != getattr(base, k)]
        return ",".join(diff) or "base"


@dataclass
class RobotWalk:
    """One walk: ``traj`` (observations, actions, true positions), the true ``heading`` (T,)
    and the robot's ``odometry`` (T, 3), and the floor plan's ``region_of``."""

    traj: Trajectory
    heading: np.ndarray
    odometry: np.ndarray
    plan: str

    def __len__(self) -> int:
        return len(self.traj)


def layout(plan: str):
    """The :class:`~topomap.worlds.arena.Layout` of ``plan``: a name, at a robot's scale (the
    robot plans as they stand, the rat plans times :data:`RAT_TO_ROBOT`), or ``name@k``, the
    plan as its file has it times ``k`` (``two_rooms@1`` is the arena's own two rooms)."""
    from topomap.worlds.arena import Layout, builtin_layout, load_floorplan

    name, _, k = plan.partition("@")
    k = float(k) if k else (1.0 if name in ROBOT_PLANS else RAT_TO_ROBOT)
    base = builtin_layout(name) if name in ("two_rooms", "four_rooms", "corridor", "open") else \
        load_floorplan(HERE / "floorplans" / f"{name}.yaml")
    if k == 1:
        return base
    return Layout(f"{name}_x{k:g}", base.boundary * k, walls=base.walls * k,
                  holes=tuple(h * k for h in base.holes), objects=base.objects * k,
                  object_types=base.object_types,
                  regions=tuple((n, p * k) for n, p in base.regions))


def world(plan: str, robot: Robot):
    from topomap.worlds.arena import ArenaWorld, RangeFinder, TurnActions

    return ArenaWorld(layout=layout(plan), dt=robot.dt, actions=TurnActions(
        angular_threshold=robot.angular_threshold),
        sensor=RangeFinder(n_beams=robot.beams, max_range=robot.max_range, frame="egocentric"),
        speed_mean=robot.speed_mean, speed_coherence_time=robot.speed_coherence_time,
        rotational_velocity_std=robot.turn_std,
        rotational_velocity_coherence_time=robot.turn_coherence_time,
        thigmotaxis=robot.thigmotaxis, wall_repel_distance=robot.wall_repel_distance)


def true_heading(positions) -> np.ndarray:
    """(T,) the heading at every step, the direction of the last move (as the arena's Motion:
    the heading the egocentric beams were cast along)."""
    from topomap.worlds.arena.kinematics import _headings

    return _headings(np.asarray(positions, dtype=np.float64))


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def wheel_odometry(positions, heading, robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """(T, 3) dead reckoning from the true moves, starting at (0, 0, 0): each step's driven
    distance times ``1 + c_v + speed_noise * e`` and turn times ``1 + c_w + turn_noise * e``
    (``c`` a calibration error drawn once per walk, within +-noise; ``e`` standard normal per
    step), plus a constant gyro bias (magnitude in [bias/2, bias], either sign) and slips
    (a Poisson ``slip_rate`` per second; each adds up to ``slip_size`` m and rad)."""
    P = np.asarray(positions, dtype=np.float64)
    T = P.shape[0]
    d = np.hypot(*np.diff(P, axis=0).T)                    # metres driven in step t -> t + 1
    dth = wrap(np.diff(heading))                           # rad turned (the move's heading)
    c_v, c_w = rng.uniform(-1, 1, 2) * (robot.speed_noise, robot.turn_noise)
    bias = rng.choice([-1, 1]) * rng.uniform(0.5, 1.0) * robot.gyro_bias
    d_hat = d * (1 + c_v + robot.speed_noise * rng.standard_normal(T - 1))
    dth_hat = dth * (1 + c_w + robot.turn_noise * rng.standard_normal(T - 1)) + bias * robot.dt
    slip = rng.random(T - 1) < robot.slip_rate * robot.dt
    d_hat[slip] += rng.uniform(0, robot.slip_size, slip.sum())
    dth_hat[slip] += rng.uniform(-robot.slip_size, robot.slip_size, slip.sum())
    theta = np.concatenate([[0.0], np.cumsum(dth_hat)])
    xy = np.zeros((T, 2))
    xy[1:] = np.cumsum(d_hat[:, None] * np.column_stack([np.cos(theta[1:]), np.sin(theta[1:])]),
                       axis=0)
    return np.column_stack([xy, wrap(theta)])


def _sense_noise(X, robot: Robot, rng) -> np.ndarray:
    X = X + rng.normal(0.0, robot.range_sigma, X.shape)
    X[rng.random(X.shape) < robot.dropout] = robot.max_range
    return np.clip(X, 0.0, robot.max_range)


def simulate(plan: str, n_steps: int, seed: int, robot: Robot = Robot()) -> RobotWalk:
    """A walk of ``n_steps`` from random motion seeded by ``seed`` (the noise of the scans and
    of the odometry drawn from streams of their own)."""
    w = world(plan, robot)
    traj = w.simulate(n_steps, None, np.random.default_rng(seed))
    rng = np.random.default_rng([seed, 1])
    heading = true_heading(traj.positions)
    traj.observations = _sense_noise(traj.observations, robot, rng)
    odo = wheel_odometry(traj.positions, heading, robot, np.random.default_rng([seed, 2]))
    return RobotWalk(traj, heading, odo, plan)


def walk(plan: str, n_steps: int, seed: int, robot: Robot = Robot(),
         cache: Path | None = None) -> RobotWalk:
    """:func:`simulate`, cached as an npz in ``cache``."""
    if cache is None:
        return simulate(plan, n_steps, seed, robot)
    name = Path(cache) / f"robot-{plan}-{robot.name()}-{seed}-{n_steps}-{walk_stamp()}.npz"
    if name.exists():
        with np.load(name, allow_pickle=False) as f:
            traj = Trajectory(f["X"], f["u"], positions=f["P"],
                              action_names=["forward", "turn_left", "turn_right", "stop"])
            return RobotWalk(traj, f["heading"], f["odometry"], plan)
    w = simulate(plan, n_steps, seed, robot)
    name.parent.mkdir(parents=True, exist_ok=True)
    np.savez(name, X=w.traj.observations, u=w.traj.actions, P=w.traj.positions,
             heading=w.heading, odometry=w.odometry)
    return w


def pair(plan: str, seed: int, robot: Robot = Robot(), cache: Path | None = None,
         n_train: int = 18_000, n_held: int = 6_000) -> tuple[RobotWalk, RobotWalk]:
    """The training walk (``seed``) and the held-out walk (``seed + 1000``) of a plan."""
    return (walk(plan, n_train, seed, robot, cache),
            walk(plan, n_held, seed + 1000, robot, cache))


def region_of(plan: str):
    return layout(plan).region_of


def odometry_drift(w: RobotWalk, window_s: float = 10.0) -> dict:
    """How the odometry drifts against the truth: the heading error after a minute (rad), the
    position error of the whole walk aligned at its start (median and max, m), and the median
    error of a ``window_s`` window's displacement (m, each window aligned at its start)."""
    P, H, O = w.traj.positions, w.heading, w.odometry
    rot = H[0] - O[0, 2]
    R = np.array([[math.cos(rot), -math.sin(rot)], [math.sin(rot), math.cos(rot)]])
    Q = (O[:, :2] - O[0, :2]) @ R.T + P[0]
    minute = int(round(60 / 0.1))
    dh = np.abs(wrap((H[minute:] - H[:-minute]) - (O[minute:, 2] - O[:-minute, 2])))
    k = int(round(window_s / 0.1))
    s = np.arange(0, len(P) - k, 7)
    errs = []
    for a in s:
        r = H[a] - O[a, 2]
        Rw = np.array([[math.cos(r), -math.sin(r)], [math.sin(r), math.cos(r)]])
        errs.append(np.linalg.norm((O[a + k, :2] - O[a, :2]) @ Rw.T - (P[a + k] - P[a])))
    e = np.linalg.norm(Q - P, axis=1)
    return {"heading_per_minute": float(np.median(dh)), "position_median": float(np.median(e)),
            "position_max": float(e.max()), "window_median": float(np.median(errs))}


def with_noise(robot: Robot, **changes) -> Robot:
    return replace(robot, **changes)
