"""map.html, the interactive map: what the figure holds, and that a browser draws it.

The browser test opens the file in headless Chromium (Debian's ``chromium`` package; ``.ci/run``
installs it): the screenshot must not be blank, and the page, once plotly has drawn it, must hold
one SVG marker (``path.point``) per state in the nodes' trace.
"""

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest

from topomap import TopologicalMap, load_trajectory
from topomap.app.run.experiment import run
from topomap.app.results import HTML_FILES
from topomap.app.plots.interactive import NODE_COLOURS, NODE_KINDS, SVG_MAX_STATES, map_figure
from topomap.app.plots.run import _state_positions, compound_mask
from topomap.worlds.office import OfficeWorld

SMALL = ["data.n_steps=400", "data.heldout_steps=0", "clusters.ns=8", "stop.n_states=14",
         "output.progress=false"]


@pytest.fixture(scope="module")
def office_run(tmp_path_factory):
    from topomap.app.compose.command_line import compose

    out = tmp_path_factory.mktemp("office")
    run(compose(SMALL), out)
    return out


def the_figure_data(html: str) -> list:
    """The traces plotly is given in the page (the JSON of ``Plotly.newPlot``)."""
    start = re.search(r'Plotly\.newPlot\(\s*"topomap-map",\s*', html).end()
    data, _ = json.JSONDecoder().raw_decode(html, start)
    return data


def node_table(traces) -> dict:
    """``{state: (x, y, colour, hover, trace name)}`` from the node traces (each hover text
    names its state)."""
    out = {}
    for t in traces:
        t = t if isinstance(t, dict) else t.to_plotly_json()
        for k, text in enumerate(t.get("hovertext") or []):
            s = int(re.match(r"<b>state (\d+)</b>", text)[1])
            colour = t["marker"]["color"]
            out[s] = (t["x"][k], t["y"][k], colour, text, t["name"])
    return out


def test_every_run_writes_a_self_contained_map_html(office_run):
    assert set(HTML_FILES) == {"map.html"}
    html = (office_run / "map.html").read_text()
    assert re.search(r"<script[^>]*\bsrc=", html) is None  # nothing fetched: plotly is inlined
    assert "Plotly.newPlot" in html and len(html) > 1_000_000
    m = TopologicalMap.load(office_run / "map.json")
    edges, heads, *nodes = the_figure_data(html)
    assert all(t["type"] == "scatter" for t in nodes) and len(node_table(nodes)) == m.n_states
    assert edges["mode"] == "lines" and heads["mode"] == "markers"
    hovers = [row[3] for row in node_table(nodes).values()]
    named = [name for text in hovers for line in re.findall(r"place: (.*?)<br>", text)
             for name in re.findall(r"(.+?) \(\d+%\)(?:, |$)", line)]  # the places by name
    assert named and set(named) <= set(OfficeWorld().place_names)


def test_nodes_sit_at_mean_positions_with_hover_and_compound_colours(office_run):
    m = TopologicalMap.load(office_run / "map.json")
    traj = load_trajectory(office_run / "trajectory.npz")
    labels = np.loadtxt(office_run / "states.csv", delimiter=",", skiprows=1, dtype=int)[:, 2]
    names = OfficeWorld().place_names  # the run's world: the paper's office
    fig = map_figure(m, labels, traj.positions, traj.places, min_prob=0.8, place_names=names)
    edges, heads, *nodes = fig.data
    table = node_table(nodes)
    means = _state_positions(labels, traj.positions, m.n_states)
    drawn = np.array([table[s][:2] for s in range(m.n_states)])
    # at the mean positions, but for nodes pushed apart to stay readable: by less than a node
    assert np.abs(drawn - means).max() < 0.05 * np.ptp(traj.positions, axis=0).max()
    compound = compound_mask(labels, traj.places, m.n_states)
    assert compound.any()
    for s in range(m.n_states):
        kind = "gds" if m.state_gds[s] >= 0 else "compound" if compound[s] else "state"
        assert table[s][2] == NODE_COLOURS[kind] and table[s][4].startswith(NODE_KINDS[kind])
        x, y = means[s]
        assert f"mean position: ({x:.2f}, {y:.2f})" in table[s][3]
    G = m.to_networkx(min_prob=0.8)
    arcs = [(a, b) for a, b in G.edges if a != b]
    assert len(heads.x) == len(arcs) and len(edges.x) == 3 * len(arcs)
    assert sum(x is None for x in edges.x) == len(arcs)  # one line, None between arcs
    for s in range(m.n_states):
        text = table[s][3]
        assert f"state {s}" in text and f"visits: {m.state_counts[s]}" in text
        assert "place: " + names[np.bincount(traj.places[labels == s]).argmax()] in text
        for y in G.successors(s):  # every arc drawn from s is listed on hover
            assert f"\u2192 {m.state_label(y)} (" in text


def test_the_title_and_legend_say_what_the_map_holds(office_run):
    m = TopologicalMap.load(office_run / "map.json")
    traj = load_trajectory(office_run / "trajectory.npz")
    labels = np.loadtxt(office_run / "states.csv", delimiter=",", skiprows=1, dtype=int)[:, 2]
    fig = map_figure(m, labels, traj.positions, traj.places)
    legend = [t.name for t in fig.data if t.showlegend is not False]
    assert any(n.startswith(NODE_KINDS["gds"]) for n in legend)  # the office has 2 GDS
    assert fig.layout.title.x < 0.1 and fig.layout.title.xanchor == "left"  # clear of the toolbar
    one_place = np.zeros(len(labels), dtype=int)  # no state is compound: the title says nothing
    title = map_figure(m, labels, traj.positions, one_place).layout.title.text
    assert "compound" not in title and "0 " not in title.split("<br>")[1]
    sizes = [t.marker.size for t in fig.data[2:]]
    assert min(min(v) for v in sizes) >= 20 and fig.data[2].textfont.size >= 10


def test_the_floor_plan_is_drawn_beneath_the_map(office_run):
    m = TopologicalMap.load(office_run / "map.json")
    walls = np.array([[[0, 0], [10, 0]], [[10, 0], [10, 7]]], dtype=float)
    fig = map_figure(m, walls=walls)
    assert fig.data[0].name == "wall" and len(fig.data[0].x) == 3 * len(walls)
    assert [v for v in fig.data[0].x if v is not None] == [0, 10, 10, 10]


def test_without_positions_a_graph_layout_places_the_nodes(office_run):
    m = TopologicalMap.load(office_run / "map.json")
    fig = map_figure(m, min_prob=0.8)
    table = node_table(fig.data[2:])
    P = np.array([table[s][:2] for s in range(m.n_states)])
    assert np.isfinite(P).all() and len(np.unique(P.round(6), axis=0)) == m.n_states
    assert "graph layout" in fig.layout.title.text
    assert all("place:" not in row[3] and "mean position" not in row[3] for row in table.values())
    again = node_table(map_figure(m, min_prob=0.8).data[2:])
    assert np.array_equal(P, np.array([again[s][:2] for s in range(m.n_states)]))  # seeded


class _Points(HTMLParser):
    """The number of ``path.point`` elements inside each plotly ``g.trace.scatter`` group."""

    def __init__(self):
        super().__init__()
        self.stack, self.traces = [], []

    def handle_starttag(self, tag, attrs):
        cls = dict(attrs).get("class") or ""
        if tag == "g":
            trace = "trace" in cls.split() and "scatter" in cls.split()
            if trace:
                self.traces.append(0)
            self.stack.append(trace)
        if tag == "path" and "point" in cls.split() and self.traces and any(self.stack):
            self.traces[-1] += 1

    def handle_startendtag(self, tag, attrs):
        if tag == "path":
            self.handle_starttag(tag, attrs)

    def handle_endtag(self, tag):
        if tag == "g" and self.stack:
            self.stack.pop()


def chromium():
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("headless Chromium is not installed (apt-get install chromium; .ci/run does)")
    return [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            "--virtual-time-budget=5000", "--window-size=1000,800"]


@pytest.mark.slow
def test_headless_chromium_draws_every_node(office_run, tmp_path):
    from matplotlib.image import imread

    browser = chromium()
    url = (office_run / "map.html").resolve().as_uri()
    m = TopologicalMap.load(office_run / "map.json")
    assert m.n_states <= SVG_MAX_STATES  # drawn as SVG, so the markers are in the page
    shot = tmp_path / "map.png"
    subprocess.run([*browser, f"--screenshot={shot}", url], capture_output=True, timeout=120,
                   check=True)
    pixels = imread(shot)[..., :3]
    dark = (pixels.mean(axis=2) < 0.5).mean()
    assert pixels.std() > 0.05 and 0.001 < dark < 0.5, dark  # lines and markers on white
    dom = subprocess.run([*browser, "--dump-dom", url], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    parser = _Points()
    parser.feed(dom)
    arcs = [(a, b) for a, b in m.to_networkx(min_prob=0.8).edges if a != b]
    assert parser.traces[:2] == [0, len(arcs)]  # the arcs' line, their arrowheads
    assert sum(parser.traces[2:]) == m.n_states  # the nodes, in a trace per kind
