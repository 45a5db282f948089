"""Random exploration in a Farama MiniGrid environment (optional: ``pip install topomap[minigrid]``).

The agent uses MiniGrid's three motion actions, ``left`` (turn 90 degrees counter-clockwise),
``right`` (turn clockwise) and ``forward``.  ``forward`` is executable only when the cell ahead can
be entered and does not end the episode: walls, closed doors and objects block it, and goal and
lava cells are never entered (so the walk is one endless episode).  The environment is made with
``gym.make(name, max_steps=10**6)`` and reset with ``seed``, which fixes the layout of
environments that randomise it (FourRooms: door gaps, start pose and goal); every ``simulate``
starts from that same reset.

Observation: derived from the 7 x 7 egocentric view (``obs["image"]``, object type per cell, with
MiniGrid's occlusion).  Each view cell becomes three 0/1 entries, *open* (empty or floor),
*wall* and *object* (door, key, ball, box, goal, lava, ...); a cell hidden from view is all zero.
The vector has 7 * 7 * 3 = 147 non-negative entries (cell ``(i, j)`` of the view, ``i`` across
and ``j`` in depth with the agent at ``(3, 6)``, channel ``c`` at index ``(i * 7 + j) * 3 + c``).

Ground truth: the pose.  Place id ``(y * width + x) * 4 + dir`` with MiniGrid's ``agent_pos``
``(x, y)`` (``y`` grows downwards) and ``agent_dir`` (0 east, 1 south, 2 west, 3 north).
``positions`` are figure coordinates with north up: the cell centre ``(x + 0.5, height - y - 0.5)``
moved 0.25 cells towards the heading, so the four headings of one cell stay apart in the figures.

Checked on: MiniGrid-Empty-5x5-v0, MiniGrid-Empty-8x8-v0, MiniGrid-Empty-16x16-v0,
MiniGrid-FourRooms-v0, MiniGrid-DoorKey-8x8-v0 (the locked door keeps the agent in its room),
MiniGrid-MultiRoom-N4-S5-v1 (closed doors keep the agent in its first room),
MiniGrid-SimpleCrossingS9N1-v0 and MiniGrid-LavaCrossingS9N1-v0 (lava never entered), with
minigrid 3.2.0.  Environments whose objects move by themselves (Dynamic-Obstacles) break the
assumption that the view is a function of the pose.
"""

from __future__ import annotations

import numpy as np

from ..core.data.trajectory import Trajectory
from .checks import check_choice, check_no_extra_actions, check_simulate_args
from .explorers import show

__all__ = ["MiniGridWorld", "MissingDependencyError", "encode_view", "VIEW_CHANNELS",
           "CHECKED_ENVS"]

ACTION_NAMES = ["left", "right", "forward"]
#: the three 0/1 entries of every view cell
VIEW_CHANNELS = ("open", "wall", "object")
#: MiniGrid object index -> channel (None: unseen, all zero)
_UNSEEN, _EMPTY, _WALL, _FLOOR = 0, 1, 2, 3
_DIR_VEC = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.int64)
_HEADINGS = ("east", "south", "west", "north")
#: cell types the agent never steps onto, although MiniGrid lets it (they end the episode)
_ENDS_EPISODE = ("goal", "lava")
#: fill colours of the cell kinds drawn in a fixed colour (other objects: a tint of their own)
_KIND_COLOURS = {"wall": (0.35, 0.35, 0.35), "goal": (0.55, 0.9, 0.55), "lava": (1.0, 0.65, 0.3)}
MAX_STEPS = 10**6
#: the environments the adapter was checked on (minigrid 3.2.0; see the module docstring)
CHECKED_ENVS = (
    "MiniGrid-Empty-5x5-v0", "MiniGrid-Empty-8x8-v0", "MiniGrid-Empty-16x16-v0",
    "MiniGrid-FourRooms-v0", "MiniGrid-DoorKey-8x8-v0", "MiniGrid-MultiRoom-N4-S5-v1",
    "MiniGrid-SimpleCrossingS9N1-v0", "MiniGrid-LavaCrossingS9N1-v0",
)


class MissingDependencyError(ImportError, ValueError):
    """The optional ``minigrid`` package is not installed (also a ValueError, so the command line
    reports it in one line)."""


def _import_minigrid():
    try:
        import gymnasium
        import minigrid  # noqa: F401  (registers the MiniGrid-* environments)
        from minigrid.minigrid_env import MiniGridEnv
    except ImportError as exc:
        raise MissingDependencyError(
            f"the minigrid world needs the optional minigrid package ({exc}); "
            'install it with: pip install "topomap[minigrid]"'
        ) from None
    return gymnasium, MiniGridEnv


def encode_view(images: np.ndarray) -> np.ndarray:
    """Observation vectors from egocentric views.

    Parameters
    ----------
    images : (T, 7, 7) or (T, 7, 7, 3) int array
        MiniGrid ``obs["image"]`` (only the object-type channel is used).

    Returns
    -------
    (T, 147) float array of 0/1 entries (see the module docstring for the layout).
    """
    img = np.asarray(images)
    if img.ndim == 4:
        img = img[..., 0]
    T = img.shape[0]
    out = np.zeros(img.shape + (3,), dtype=np.float64)
    out[..., 0] = (img == _EMPTY) | (img == _FLOOR)
    out[..., 1] = img == _WALL
    out[..., 2] = (img != _UNSEEN) & (img != _EMPTY) & (img != _FLOOR) & (img != _WALL)
    return out.reshape(T, -1)


class MiniGridWorld:
    """A MiniGrid environment explored with left / right / forward.

    Parameters
    ----------
    name : str
        A registered MiniGrid environment id, e.g. ``"MiniGrid-Empty-8x8-v0"`` or
        ``"MiniGrid-FourRooms-v0"``.
    seed : int
        Seed of the environment's reset (fixes randomised layouts and the start pose).
    extra_actions : list, optional
        Not supported: a non-empty list raises ValueError.

    Raises
    ------
    MissingDependencyError
        When minigrid is not installed.
    ValueError
        For an unknown or non-MiniGrid ``name``.
    """

    def __init__(self, name: str = "MiniGrid-Empty-8x8-v0", seed: int = 0, extra_actions=None):
        check_no_extra_actions("minigrid", extra_actions)
        gym, MiniGridEnv = _import_minigrid()
        if not isinstance(name, str) or not name:
            raise ValueError(f"name must name a MiniGrid environment, got {name!r}")
        try:
            env = gym.make(name, max_steps=MAX_STEPS)
        except gym.error.Error as exc:
            n = sum(e.startswith("MiniGrid-") for e in gym.registry)
            raise ValueError(f"name={name!r} is not a registered gymnasium environment ({exc}); "
                             f"{n} MiniGrid ids are registered, checked ones: "
                             f"{', '.join(CHECKED_ENVS)}") from None
        except TypeError:  # its constructor does not take MiniGrid's max_steps
            raise ValueError(f"name={name!r} is not a MiniGrid environment") from None
        if not isinstance(env.unwrapped, MiniGridEnv):
            env.close()
            raise ValueError(f"name={name!r} is not a MiniGrid environment")
        #: the MiniGrid environment id
        self.env_id = name
        self.seed = int(seed)
        self._env = env
        u = env.unwrapped
        u.reset(seed=self.seed)
        self.width, self.height = int(u.width), int(u.height)
        #: the layout after the seeded reset: (width, height, 3) MiniGrid encoding
        self.grid_encoding = u.grid.encode()
        self.start_pose = (int(u.agent_pos[0]), int(u.agent_pos[1]), int(u.agent_dir))
        self._enterable = self._enterable_cells(u.grid)
        self.action_names = list(ACTION_NAMES)

    # ------------------------------------------------------------------ poses and places
    @property
    def n_actions(self) -> int:
        return len(self.action_names)

    def _enterable_cells(self, grid) -> np.ndarray:
        ok = np.zeros((self.width, self.height), dtype=bool)
        for x in range(self.width):
            for y in range(self.height):
                obj = grid.get(x, y)
                ok[x, y] = obj is None or (obj.can_overlap() and obj.type not in _ENDS_EPISODE)
        return ok

    def place_id(self, x, y, direction):
        """Place id of pose ``(x, y, direction)`` (works on arrays too)."""
        return (np.asarray(y) * self.width + np.asarray(x)) * 4 + np.asarray(direction)

    def pose_of(self, place):
        """``(x, y, direction)`` of a place id (works on arrays too)."""
        place = np.asarray(place)
        cell, d = np.divmod(place, 4)
        y, x = np.divmod(cell, self.width)
        return x, y, d

    @property
    def place_names(self) -> list[str]:
        """Each place's name, for the interactive map: MiniGrid's cell and the heading,
        ``(x, y) facing east``."""
        x, y, d = self.pose_of(np.arange(self.width * self.height * 4))
        return [f"({a}, {b}) facing {_HEADINGS[c]}" for a, b, c in zip(x, y, d)]

    def position_of(self, place) -> np.ndarray:
        """Figure coordinates of places: cell centre (north up) nudged towards the heading."""
        x, y, d = self.pose_of(place)
        v = _DIR_VEC[d]
        return np.stack([x + 0.5 + 0.25 * v[..., 0], self.height - y - 0.5 - 0.25 * v[..., 1]],
                        axis=-1).astype(np.float64)

    def executable_mask(self, x: int, y: int, direction: int) -> np.ndarray:
        """``[left, right, forward]``: forward only when the cell ahead can be entered."""
        fx, fy = x + _DIR_VEC[direction, 0], y + _DIR_VEC[direction, 1]
        fwd = 0 <= fx < self.width and 0 <= fy < self.height and bool(self._enterable[fx, fy])
        return np.array([True, True, fwd])

    def step_pose(self, x: int, y: int, direction: int, action: int) -> tuple[int, int, int]:
        """The pose after ``action`` by MiniGrid's rules (forward assumed executable)."""
        if action == 0:
            return x, y, (direction - 1) % 4
        if action == 1:
            return x, y, (direction + 1) % 4
        return x + int(_DIR_VEC[direction, 0]), y + int(_DIR_VEC[direction, 1]), direction

    def reachable_places(self) -> np.ndarray:
        """Sorted ids of every pose reachable from the start pose (the true places)."""
        seen = {self.start_pose}
        todo = [self.start_pose]
        while todo:
            pose = todo.pop()
            mask = self.executable_mask(*pose)
            for a in np.flatnonzero(mask):
                nxt = self.step_pose(*pose, int(a))
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return np.sort([int(self.place_id(*p)) for p in seen])

    def observe(self, place: int) -> np.ndarray:
        """Noise-free observation vector (147,) of the pose ``place``, from MiniGrid's own view."""
        x, y, d = (int(v) for v in self.pose_of(place))
        if not (0 <= x < self.width and 0 <= y < self.height and 0 <= d < 4):
            raise ValueError(f"place {place} is outside the {self.width} x {self.height} grid")
        u = self._env.unwrapped
        u.agent_pos, u.agent_dir = (x, y), d
        return encode_view(u.gen_obs()["image"][None])[0]

    # ------------------------------------------------------------------ simulation
    def place_graph(self):
        """The true topology, for navigation (:mod:`topomap.worlds.navigation`): the poses
        reachable from the start pose and the moves between them."""
        from .navigation import explored_graph

        def step(place):
            pose = tuple(int(v) for v in self.pose_of(place))
            mask = self.executable_mask(*pose)
            return [int(self.place_id(*self.step_pose(*pose, a))) if mask[a] else -1
                    for a in range(self.n_actions)]

        start = int(self.place_id(*self.start_pose))
        return explored_graph(self.width * self.height * 4, self.n_actions, [start], step,
                              self.observe, lambda place: -1)

    def simulate(self, n_steps: int, explorer, rng: np.random.Generator) -> Trajectory:
        """Random walk of ``n_steps`` steps from the seeded reset's start pose.

        ``explorer.choose(mask, rng)`` is called once per step with the mask
        ``[left, right, forward]``; the last step's action is chosen but not executed.  Should the
        environment end an episode anyway, the next step starts a new one from the same seeded
        reset and ``lengths`` records the episodes.
        """
        T = check_simulate_args(n_steps, explorer)
        u = self._env.unwrapped
        u.max_steps = max(MAX_STEPS, T + 1)
        obs, _ = u.reset(seed=self.seed)
        views = np.empty((T, 7, 7), dtype=np.uint8)
        poses = np.empty((T, 3), dtype=np.int64)
        actions = np.empty(T, dtype=np.int64)
        starts = [0]
        sees = hasattr(explorer, "see")
        for t in range(T):
            views[t] = obs["image"][:, :, 0]
            x, y, d = int(u.agent_pos[0]), int(u.agent_pos[1]), int(u.agent_dir)
            poses[t] = (x, y, d)
            mask = self.executable_mask(x, y, d)
            if sees:
                show(explorer, encode_view(views[t:t + 1])[0], mask, -1, t)
            a = check_choice(explorer.choose(mask, rng), mask, t)
            actions[t] = a
            if t + 1 < T:
                obs, _, terminated, truncated, _ = u.step(a)
                if terminated or truncated:
                    obs, _ = u.reset(seed=self.seed)
                    starts.append(t + 1)
        places = self.place_id(poses[:, 0], poses[:, 1], poses[:, 2]).astype(np.int64)
        lengths = np.diff(starts + [T]) if len(starts) > 1 else None
        meta = {
            "world": "minigrid", "env_id": self.env_id, "seed": self.seed,
            "width": self.width, "height": self.height,
            "place_encoding": "(y * width + x) * 4 + dir",
            "view_channels": list(VIEW_CHANNELS), "n_episodes": len(starts),
        }
        return Trajectory(
            observations=encode_view(views), actions=actions, places=places,
            positions=self.position_of(places), lengths=lengths,
            action_names=list(self.action_names), meta=meta,
        )

    # ------------------------------------------------------------------ figures
    def _layout_image(self):
        """RGB image of the layout (row 0 at the top) and the kinds of cell it shows."""
        from minigrid.core.constants import COLORS, IDX_TO_COLOR, IDX_TO_OBJECT

        img = np.ones((self.height, self.width, 3))
        kinds = {}
        for x in range(self.width):
            for y in range(self.height):
                kind = IDX_TO_OBJECT[int(self.grid_encoding[x, y, 0])]
                colour = COLORS[IDX_TO_COLOR[int(self.grid_encoding[x, y, 1])]] / 255.0
                if kind in ("empty", "floor", "unseen"):
                    continue
                img[y, x] = _KIND_COLOURS.get(kind, 0.5 + 0.5 * colour)
                kinds.setdefault(kind, img[y, x].copy())
        return img, kinds

    def heading_glyphs(self) -> np.ndarray:
        """``(n, 3, 2)`` triangles, one per reachable pose: at the pose's figure position
        (:meth:`position_of`), pointing along its heading (north up)."""
        places = self.reachable_places()
        _, _, d = self.pose_of(places)
        centre = self.position_of(places)
        v = _DIR_VEC[d] * np.array([1, -1])  # figure coordinates: y grows northwards
        side = np.column_stack([-v[:, 1], v[:, 0]]) * 0.09
        return np.stack([centre + 0.15 * v, centre - 0.08 * v + side, centre - 0.08 * v - side],
                        axis=1)

    def plot_room(self, ax, labels: bool = False):
        """Draw the layout (north up): walls dark, goal green, lava orange, doors and objects in
        their colour, and a grey triangle per reachable pose pointing along its heading; a legend
        beside the room.  ``labels`` marks the start pose.  Returns ``ax``."""
        from matplotlib.collections import PolyCollection
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch

        img, kinds = self._layout_image()
        ax.imshow(img, origin="upper", extent=(0, self.width, 0, self.height),
                  interpolation="nearest", zorder=0)
        ax.add_collection(PolyCollection(self.heading_glyphs(), facecolors="0.72",
                                         edgecolors="none", zorder=1))
        handles = [Line2D([], [], ls="none", marker=">", ms=6, color="0.72",
                          label="pose (its heading)")]
        handles += [Patch(fc=c, ec="0.5", lw=0.5, label=k) for k, c in kinds.items()]
        if labels:
            sx, sy = self.position_of(self.place_id(*self.start_pose))
            ax.plot([sx], [sy], "r*", ms=8)
            handles.append(Line2D([], [], ls="none", marker="*", ms=8, color="red",
                                  label="start pose"))
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5,
                  frameon=False)
        ax.set_xlim(0, self.width)
        ax.set_ylim(0, self.height)
        ax.set_aspect("equal")
        return ax

    def close(self) -> None:
        self._env.close()

    def __repr__(self) -> str:
        return f"MiniGridWorld(name={self.env_id!r}, seed={self.seed})"
