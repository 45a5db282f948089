"""Drawing the office room with matplotlib."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_room", "type_colours"]


#: colour words of type names ("blue desk"): the base colour and the range of shades that the
#: types of that colour are spread over, from darker (negative: mixed with black) to lighter
#: (positive: mixed with white)
_FAMILIES = {
    "red": ("#d62728", -0.4, 0.45), "blue": ("#1f77b4", -0.45, 0.5),
    "green": ("#2ca02c", -0.45, 0.5), "gray": ("#8c8c8c", -0.45, 0.5),
    "grey": ("#8c8c8c", -0.45, 0.5), "yellow": ("#f5d000", -0.3, 0.4),
    "white": ("#ffffff", -0.2, 0.0), "black": ("#000000", 0.0, 0.5),
    "brown": ("#8c564b", -0.4, 0.45), "orange": ("#ff7f0e", -0.35, 0.4),
    "purple": ("#9467bd", -0.4, 0.45),
}
#: colours of types whose name has no colour word
_OTHER = ("#17becf", "#e377c2", "#bcbd22", "#7b4173", "#393b79", "#637939", "#843c39")


def _shade(base, t):
    """``base`` mixed with black (``t < 0``) or with white (``t > 0``) by ``|t|``."""
    from matplotlib.colors import to_rgb

    rgb = np.array(to_rgb(base))
    return tuple(rgb * (1 + t) if t < 0 else rgb + (1 - rgb) * t)


def type_colours(type_names) -> list:
    """One fill colour per object type, matching its name's colour word ("red wall" red, "blue
    desk" and "blue chair" two shades of blue); types without one get distinct other hues."""
    family = [next((w for w in str(n).lower().split() if w in _FAMILIES), None)
              for n in type_names]
    colours, others = [], 0
    for t, f in enumerate(family):
        if f is None:
            colours.append(_OTHER[others % len(_OTHER)])
            others += 1
            continue
        base, lo, hi = _FAMILIES[f]
        same = [u for u in range(len(type_names)) if family[u] == f]
        shades = np.linspace(lo, hi, len(same)) if len(same) > 1 else [0.0]
        colours.append(_shade(base, shades[same.index(t)]))
    return colours


def _legend(world, ax, colours, show_corners):
    """The legend beside the room: one entry per object type, then the GDS ranges and corners."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [Patch(fc=colours[t], ec="black", lw=0.6, label=world.type_names[t])
               for t in np.unique(world.object_types)]
    if world.n_gds:
        handles.append(Line2D([], [], ls="none", marker="o", ms=9, mfc="none", mec="red",
                              label="GDS: recognition range"))
    if show_corners:
        handles.append(Line2D([], [], ls="none", marker="+", ms=6, color="black",
                              label="corner place"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5,
              title="object type", title_fontsize=7, frameon=False)


def _overlaps(box, boxes) -> bool:
    """Whether the display box ``box`` overlaps any of ``boxes``."""
    return any(box.overlaps(b) for b in boxes)


def _label_places(world, ax, points, radii, objects, names):
    """Write each place's id next to it, on the first side (towards the room's middle first)
    where the text meets no other label, object (``objects``: their display boxes) or GDS name;
    a place with no free side is left unlabelled."""
    to_pt = ax.bbox.width * 72.0 / ax.figure.dpi / abs(np.subtract(*ax.get_xlim()))
    middle = np.array([world.width, world.height]) / 2
    sides = np.array([[0, 1], [0, -1], [1, 0], [-1, 0]], dtype=float)
    align = [("center", "bottom"), ("center", "top"), ("left", "center"), ("right", "center")]
    written = []
    for p, (c, r) in enumerate(zip(points, radii)):
        order = np.argsort(-(sides @ (middle - c)), kind="stable")
        others = [b for i, b in enumerate(objects) if i != p] + names + written
        for k in order:
            ha, va = align[k]
            text = ax.annotate(str(p), c, xytext=sides[k] * (r * to_pt + 2.0),
                               textcoords="offset points", ha=ha, va=va, fontsize=6.5)
            box = text.get_window_extent()
            if not _overlaps(box, others):
                written.append(box)
                break
            text.remove()


def plot_room(world, ax, labels: bool = True, show_corners: bool = True):
    """Draw ``world``'s room on a matplotlib Axes: walls, objects coloured by type with a legend
    of the types beside the room, GDS recognition ranges as dashed circles.  ``labels`` writes each
    place's id (as in a trajectory's ``places``) next to it wherever it collides with no other
    text or object.  Returns ``ax``."""
    from matplotlib.patches import Circle, Rectangle

    w = world
    ax.add_patch(Rectangle((0, 0), w.width, w.height, fill=False, lw=2.5, ec="black"))
    colours = type_colours(w.type_names)
    circles = [ax.add_patch(Circle(w.object_positions[i], w.object_radii[i],
                                   fc=colours[int(w.object_types[i])], ec="black", lw=0.8))
               for i in range(w.n_objects)]
    names = []
    for k, i in enumerate(w.gds_places):
        c, r = w.object_positions[i], w.object_radii[i]
        ax.add_patch(Circle(c, r + w.reach, fill=False, ls="--", lw=1.2, ec="red"))
        names.append(ax.annotate(w.gds_names[k], c + np.array([0, -(r + w.reach) - 0.15]),
                                 ha="center", va="top", fontsize=7, color="red"))
    if show_corners:
        corners = w.place_positions[w.n_objects:]
        ax.plot(corners[:, 0], corners[:, 1], "k+", ms=6)
    ax.set_xlim(-0.5, w.width + 0.5)
    ax.set_ylim(-0.5, w.height + 0.5)
    ax.set_aspect("equal")
    _legend(w, ax, colours, show_corners)
    if labels:
        n = w.n_places if show_corners else w.n_objects
        radii = np.concatenate([w.object_radii, np.full(w.n_places - w.n_objects, 0.15)])
        ax.apply_aspect()
        _label_places(w, ax, w.place_positions[:n], radii[:n],
                      [c.get_window_extent() for c in circles],
                      [t.get_window_extent() for t in names])
    return ax
