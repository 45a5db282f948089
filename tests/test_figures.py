"""The figures read at a glance: measurable properties of what each plotting function draws.

Every test draws on a matplotlib Axes (Agg) and inspects its artists, not a PNG file.
"""

import itertools

import matplotlib.colors as mcolors
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from topomap import MapLearner
from topomap.app import plots
from topomap.app.report.figure import plot_sweep_line
from topomap.metrics import compound_states
from topomap.core.data.trajectory import Trajectory


def _axes(size=(6, 4.5)):
    """A fresh Axes on an Agg canvas of ``size`` inches."""
    fig = Figure(figsize=size, dpi=100)
    FigureCanvasAgg(fig)
    return fig.add_subplot()


def _lab(colour):
    """CIELAB (D65) of a matplotlib colour: an independent check of the palette's spacing."""
    rgb = np.array(mcolors.to_rgb(colour))
    lin = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                    [0.0193, 0.1192, 0.9505]]) @ lin / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16 / 116)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def _labelling(n_states=30, compound=(1, 3, 7), steps=12, seed=0):
    """A hand-made run: state ``s`` sits at place ``s`` (on a 6-wide grid, 3 m apart); each state
    of ``compound`` also holds ``steps // 3`` steps of place ``n_states + s``.  Returns the
    trajectory (positions = place centres) and the labels."""
    rng = np.random.default_rng(seed)
    labels, places = [], []
    for s in range(n_states):
        labels += [s] * steps
        places += [s] * steps
        if s in compound:
            labels += [s] * (steps // 3)
            places += [n_states + s] * (steps // 3)
    labels, places = np.array(labels), np.array(places)
    centre = np.column_stack([places % 6, places // 6]) * 3.0
    T = len(labels)
    traj = Trajectory(observations=rng.normal(size=(T, 2)), actions=np.zeros(T, dtype=int),
                      places=places, positions=centre.astype(float))
    return traj, labels


# ---------------------------------------------------------------------------- fig_states
@pytest.mark.parametrize("n", [22, 30, 48])
def test_state_palette_is_distinct_and_not_pale(n):
    styles = plots.state_styles(n)
    assert len(set(styles)) == n  # (colour, marker) tells every state apart
    colours = [c for c, _ in styles[:len(plots.PALETTE)]]
    assert len(set(colours)) == min(n, len(plots.PALETTE))
    lab = np.array([_lab(c) for c in colours])
    gaps = [np.linalg.norm(a - b) for a, b in itertools.combinations(lab, 2)]
    assert min(gaps) >= 20  # CIELAB units: clearly different colours
    assert lab[:, 0].max() <= 80  # lightness: none near white


def test_states_figure_draws_distinct_non_pale_styles():
    """What the figure draws (not just the palette): every state's points in one colour and
    marker of their own, none near white."""
    traj, labels = _labelling(n_states=30, compound=())
    ax = plots.plot_states(_axes(), traj, labels)
    styles = set()
    for coll in ax.collections:
        if coll.get_label().startswith("compound"):
            continue
        marker = tuple(np.round(coll.get_paths()[0].vertices, 3).ravel())
        for rgba in coll.get_facecolors():
            styles.add((tuple(np.round(rgba[:3], 3)), marker))
            assert _lab(rgba[:3])[0] <= 80
    assert len(styles) == 30


def test_states_figure_numbers_every_state_at_its_mean():
    traj, labels = _labelling(n_states=30, compound=())
    ax = plots.plot_states(_axes(), traj, labels)
    texts = {t.get_text(): np.array(t.get_position()) for t in ax.texts}
    assert set(texts) == {str(s) for s in range(30)}
    for s in range(30):
        assert np.allclose(texts[str(s)], traj.positions[labels == s].mean(axis=0), atol=0.05)


def test_compound_states_are_ringed_and_numbered_at_each_place():
    compound = (1, 3, 7)
    traj, labels = _labelling(n_states=12, compound=compound)
    ax = plots.plot_states(_axes(), traj, labels)
    (rings,) = [c for c in ax.collections if c.get_label().startswith("compound")]
    ringed = set()
    for x, y in rings.get_offsets():
        (text,) = [t for t in ax.texts if np.allclose(t.get_position(), (x, y), atol=0.05)]
        ringed.add(int(text.get_text()))
    assert ringed == set(compound)
    assert len(ringed) == compound_states(traj.places, labels)
    assert len(rings.get_offsets()) == 2 * len(compound)  # one ring on each of their places
    assert any(t.get_text().startswith("compound state (3)") for t in ax.get_legend().get_texts())


def test_states_figure_is_deterministic():
    traj, labels = _labelling()
    a, b = (plots.plot_states(_axes(), traj, labels) for _ in range(2))
    for ca, cb in zip(a.collections, b.collections):
        assert np.array_equal(ca.get_offsets(), cb.get_offsets())


# ---------------------------------------------------------------------------- the map
@pytest.fixture(scope="module")
def small_run():
    """A small gridroom walk (aliased: 3 symbols in 16 cells) and the map learned from it."""
    from topomap.worlds.explorers import RandomExplorer
    from topomap.worlds.table.gridroom import GridRoom

    world = GridRoom(width=4, height=4, n_symbols=3, seed=1)
    traj = world.simulate(600, RandomExplorer(), np.random.default_rng(0))
    noise = np.random.default_rng(1).normal(0, 0.05, traj.observations.shape)
    traj = Trajectory(observations=traj.observations + noise, actions=traj.actions,
                      places=traj.places, positions=traj.positions,
                      action_names=traj.action_names)
    learner = MapLearner(n_clusters=3, n_states=20, n_init=1).fit_trajectory(traj)
    return world, traj, learner


def test_map_nodes_are_numbered_and_never_overlap(small_run):
    world, traj, learner = small_run
    ax = plots.plot_map(_axes((8, 6)), traj, learner, world)
    ax.figure.canvas.draw()
    assert {t.get_text() for t in ax.texts} == {str(s) for s in range(learner.map_.n_states)}
    nodes = np.vstack([c.get_offsets() for c in ax.collections if c.get_label() in
                       {label for *_, label in plots.graph.NODE_KINDS}])
    assert len(nodes) == learner.map_.n_states
    pixels = ax.transData.transform(nodes)
    diameter = 11.0 * ax.figure.dpi / 72  # the numbered nodes' diameter, in pixels
    gaps = [np.hypot(*(a - b)) for a, b in itertools.combinations(pixels, 2)]
    assert min(gaps) >= 0.99 * diameter


def test_map_marks_compound_states_in_its_legend(small_run):
    world, traj, learner = small_run
    ax = plots.plot_map(_axes((8, 6)), traj, learner, world)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(label.startswith("compound state") for label in labels)
    assert any(label.startswith("symbol") for label in labels)  # the room's tints, explained
    (coll,) = [c for c in ax.collections if c.get_label().startswith("compound state")]
    assert (learner.map_.state_gds < 0).all()  # no GDS in a gridroom: every compound is drawn so
    assert len(coll.get_offsets()) == compound_states(traj.places, learner.labels_) > 0


# ---------------------------------------------------------------------------- the office room
def _overlapping(boxes):
    """The pairs of display boxes that overlap."""
    return [(a, b) for a, b in itertools.combinations(boxes, 2) if a.overlaps(b)]


def test_office_room_has_a_type_legend_and_no_overlapping_labels():
    from topomap.worlds.office import OfficeWorld

    world = OfficeWorld()
    ax = _axes((8, 6))
    world.plot_room(ax)
    ax.figure.canvas.draw()
    renderer = ax.figure.canvas.get_renderer()
    legend = ax.get_legend()
    entries = [t.get_text() for t in legend.get_texts()]
    assert sorted(e for e in entries if e in world.type_names) == sorted(world.type_names)
    assert len(entries) == world.n_types + 2  # plus the GDS range and the corner mark
    fills = [tuple(h.get_facecolor()) for h, e in zip(legend.legend_handles, entries)
             if e in world.type_names]
    assert len(set(fills)) == world.n_types
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    assert len(boxes) >= world.n_places - 3  # nearly every place is labelled
    assert _overlapping(boxes) == []


def test_office_type_colours_follow_the_names():
    from topomap.worlds.office.plot import type_colours

    names = ["red wall", "blue desk", "blue chair", "computer"]
    r, b1, b2, other = (np.array(mcolors.to_rgb(c)) for c in type_colours(names))
    assert r[0] > r[1] + 0.2 and r[0] > r[2] + 0.2
    assert b1[2] > b1[0] and b2[2] > b2[0] and not np.allclose(b1, b2)
    assert len({tuple(r), tuple(b1), tuple(b2), tuple(other)}) == 4


# ---------------------------------------------------------------------------- MiniGrid headings
def test_minigrid_room_draws_a_heading_glyph_per_pose():
    pytest.importorskip("minigrid")
    from topomap.worlds.minigrid import MiniGridWorld

    world = MiniGridWorld("MiniGrid-Empty-5x5-v0")
    ax = world.plot_room(_axes())
    (glyphs,) = [c for c in ax.collections if isinstance(c, PolyCollection)]
    places = world.reachable_places()
    tri = np.array([p.vertices[:3] for p in glyphs.get_paths()])
    assert len(tri) == len(places) == 32  # 3 x 3 open cells but the goal, 4 headings each
    _, _, d = world.pose_of(places)
    north_up = {0: (1, 0), 1: (0, -1), 2: (-1, 0), 3: (0, 1)}
    tip = tri[:, 0] - tri.mean(axis=1)
    for heading, v in zip(d, tip):
        assert np.allclose(v / np.hypot(*v), north_up[int(heading)], atol=1e-9)
    assert np.allclose(tri.mean(axis=1), world.position_of(places), atol=0.05)
    world.close()


# ---------------------------------------------------------------------------- sweep line
ROWS = [{"job": 0, "clusters.ns": "10", "status": "completed", "ari": 0.958},
        {"job": 1, "clusters.ns": "20", "status": "completed", "ari": 0.970},
        {"job": 2, "clusters.ns": "30", "status": "failed", "ari": None}]


def test_sweep_line_draws_no_value_for_a_failed_job():
    ax = _axes()
    plot_sweep_line(ax, ROWS, "clusters.ns", "ari", "final ARI", best=ROWS[1])
    for line in ax.lines:
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        assert not np.isfinite(y[x == 30]).any(), line.get_label()
    x30 = ax.transData.transform((30, 0))[0]
    (band,) = [p for p in ax.patches if p.get_hatch()]  # the failed value, marked across the plot
    assert band.get_extents().x0 < x30 < band.get_extents().x1
    assert any("failed" in t.get_text() for t in ax.texts)
    assert any("failed" in t.get_text() for t in ax.get_legend().get_texts())
    ticks = {t.get_text(): t.get_color() for t in ax.get_xticklabels()}
    assert mcolors.to_hex(ticks["30"]) == mcolors.to_hex("tab:red")


# ---------------------------------------------------------------------------- a refined run
@pytest.fixture(scope="module")
def refined_run(small_run):
    """The small gridroom walk learned with the EM refinement after the split."""
    world, traj, _ = small_run
    learner = MapLearner(n_clusters=3, n_states=20, n_init=1, refine="em").fit_trajectory(traj)
    assert learner.map_ is not learner.map_split_  # the refinement was kept
    return world, traj, learner


def _written_figures(monkeypatch, tmp_path, traj, learner, world):
    """``{file name: Figure}`` of what :func:`plots.write_figures` draws (not saved)."""
    figures = {}
    monkeypatch.setattr(plots.run, "save_figure", lambda fig, path: figures.update({path.name: fig}))
    plots.write_figures(tmp_path, traj, learner, world)
    for fig in figures.values():
        FigureCanvasAgg(fig)
    return figures


def test_states_figure_of_a_refined_run_names_each_stage(refined_run, monkeypatch, tmp_path):
    """The split map and the refined map each get their panel, titled by their stage."""
    world, traj, learner = refined_run
    fig = _written_figures(monkeypatch, tmp_path, traj, learner, world)["fig_states.png"]
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[1] == f"after splitting: {learner.map_split_.n_states} states"
    assert titles[2] == f"after the refinement: {learner.map_.n_states} states"
    rings = [c for c in fig.axes[1].collections if c.get_label().startswith("compound")]
    assert len(rings[0].get_offsets()) >= compound_states(traj.places, learner.labels_split_)


def test_split_figure_of_a_refined_run_shows_the_split(refined_run, monkeypatch, tmp_path):
    world, traj, learner = refined_run
    fig = _written_figures(monkeypatch, tmp_path, traj, learner, world)["fig_split.png"]
    state = learner.split_history_[0]["state"]
    made = np.unique(learner.labels_split_[learner.labels_phase1_ == state])
    assert fig.axes[1].get_title() == f"after splitting: states {', '.join(map(str, made))}"


def test_split_figure_leaves_no_blank_band_below_its_tables(small_run, monkeypatch, tmp_path):
    world, traj, learner = small_run
    fig = _written_figures(monkeypatch, tmp_path, traj, learner, world)["fig_split.png"]
    renderer = fig.canvas.get_renderer()
    tables = [t for ax in fig.axes for t in ax.tables]
    assert tables
    bottom = min(t.get_window_extent(renderer).y0 for t in tables)
    axes_bottom = min(ax.get_window_extent(renderer).y0 for ax in fig.axes if ax.tables)
    assert (bottom - axes_bottom) / fig.bbox.height < 0.04


def test_entropy_figure_labels_the_refinement_and_keeps_its_legend_off_the_curves(refined_run):
    _, _, learner = refined_run
    ax = plots.plot_entropy(_axes((6.5, 3.5)), learner)
    ax.figure.canvas.draw()
    renderer = ax.figure.canvas.get_renderer()
    assert any(t.get_text().strip() == "refined" for t in ax.texts)
    names = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"after the refinement ({learner.map_.n_states} states)" in names
    assert not ax.get_legend().get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
    split = [r for r in learner.entropies_ if r.get("stage") != "refined"]
    (last,) = [r for r in learner.entropies_ if r.get("stage") == "refined"][-1:]
    refined = [last["H_u"], last["H_x"], last["H_u"] + last["H_x"]]
    lo, hi = ax.get_ylim()
    assert all(lo <= v <= hi for v in refined)  # every refined value on the axis, none off it
    drawn = [v for r in split for v in (r["H_u"], r["H_x"], r["H_u"] + r["H_x"])] + refined
    span = max(drawn) - min(drawn)  # the range is the data's, padded a little
    assert min(drawn) - 0.1 * span <= lo and hi <= max(drawn) + 0.1 * span


class _Entropies:
    """A learner's entropy trace made by hand: ten splits, then a refinement whose H(x'|x,u) is
    0 (every transition certain), below every value of the split."""

    entropies_ = [{"n_states": 10 + k, "H_u": 2.0 - 0.01 * k, "H_x": 0.5 - 0.02 * k}
                  for k in range(10)] + [{"stage": "refined", "n_states": 19, "H_u": 1.7,
                                          "H_x": 0.0}]


def test_entropy_figure_draws_a_refined_zero_on_its_axis():
    ax = plots.plot_entropy(_axes((6.5, 3.5)), _Entropies())
    lo, hi = ax.get_ylim()
    assert lo <= 0.0 <= hi
    refined = [float(line.get_ydata()[0]) for line in ax.lines if len(line.get_xdata()) == 1]
    assert sorted(refined) == [0.0, 1.7, 1.7]  # H(x'|x,u), H(u|x) and their sum, as points
    assert all(line.get_clip_on() for line in ax.lines)  # nothing drawn off the axis


# ---------------------------------------------------------------------------- readable numbers
def test_numbers_of_states_at_one_spot_do_not_overlap():
    """Twelve states of two and three digits whose steps sit at one spot (and a few nearby): every
    number is written, and no two numbers' boxes overlap."""
    rng = np.random.default_rng(0)
    states = np.array([7, 25, 27, 98, 99, 100, 101, 102, 120, 131, 86, 49])
    labels = np.repeat(states, 5)
    spot = np.where(np.isin(labels, [86, 131, 49]), 0.3, 0.0)  # three a little apart
    positions = np.column_stack([2.0 + spot, 1.0 + 0.02 * spot]) + rng.normal(0, 1e-3, (60, 2))
    traj = Trajectory(observations=rng.normal(size=(60, 2)), actions=np.zeros(60, dtype=int),
                      positions=positions)
    ax = plots.plot_states(_axes((6, 4.5)), traj, labels)
    ax.figure.canvas.draw()
    renderer = ax.figure.canvas.get_renderer()
    numbers = [t for t in ax.texts if t.get_text().isdigit()]
    assert sorted(int(t.get_text()) for t in numbers) == sorted(states)
    assert _overlapping([t.get_window_extent(renderer) for t in numbers]) == []


def test_the_corner_places_show_around_the_map_nodes_on_them():
    from topomap.worlds import OfficeWorld, RandomExplorer

    world = OfficeWorld()
    traj = world.simulate(300, RandomExplorer(), np.random.default_rng(0))
    learner = MapLearner(n_clusters=8, n_states=12, n_init=1).fit_trajectory(traj)
    ax = plots.plot_map(_axes((8, 6)), traj, learner, world)
    (corners,) = [line for line in ax.lines if line.get_marker() == "+"]
    assert corners.get_markersize() > 11.0  # wider than a numbered node: its arms show
    nodes = max(c.get_zorder() for c in ax.collections if c.get_label() == "learned state")
    assert corners.get_zorder() < nodes  # beneath the nodes, so the numbers stay readable


def test_the_mapping_figure_shows_heldout_ari_with_its_legend_clear_of_the_axes():
    curve = [{"steps": 250 * k, "ari": 0.9 - 0.05 * k, "heldout_ari": 0.1 * k} for k in (1, 2, 3)]
    ax = plots.plot_mapping(_axes((5.5, 3.8)), curve,
                            "HistoryExplorer(update_every=250, context=3, epsilon=0.0)")
    ax.figure.canvas.draw()
    renderer = ax.figure.canvas.get_renderer()
    lines = {line.get_label(): list(line.get_ydata()) for line in ax.lines}
    (held,) = [y for name, y in lines.items() if "heldout_ari" in name]
    assert held == pytest.approx([0.1, 0.2, 0.3])
    assert ax.get_title() == "mapping while exploring: HistoryExplorer"
    legend = ax.get_legend().get_window_extent(renderer)
    assert legend.y1 <= ax.xaxis.get_tightbbox(renderer).y0  # below the ticks and their label
