"""What a run leaves, named once: the files of its folder and the numbers in them.

The runner (:mod:`topomap.app.run`) writes these files, the sweep report
(:mod:`topomap.app.report`) and the loggers (:mod:`topomap.app.components.loggers`) read them
back, and an optimising sweeper is given one of the numbers: each reads the names from here, so
none of them imports another to learn a file's name.

* the files: :data:`OUTPUT_FILES` (every run), :data:`FIGURE_FILES`, :data:`HTML_FILES`,
  :data:`PATH_FIGURES` and :data:`MAPPING_FIGURES` (with ``output.figures``),
  :data:`LOCALIZE_FILES` (``task=localize``), :data:`STATUS_FILE` and, in a sweep's folder,
  :data:`CACHE_DIR` and a search's :data:`STUDY_FILE`;
* the numbers of ``metrics.json`` (and ``status.json``) by name, :data:`COLUMNS`: where each is,
  its label and which way is better -- the columns of a sweep's ``summary.csv`` and a logger's
  metrics;
* the numbers a run can return to an optimising sweeper, :data:`OBJECTIVES`;
* the units of the less obvious numbers, :data:`UNITS`.
"""

from __future__ import annotations

import functools
import operator
from dataclasses import dataclass
from typing import Any

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from ..core.checks import ParameterError

__all__ = ["METRICS_FILE", "STATUS_FILE", "CACHE_DIR", "STUDY_FILE", "OUTPUT_FILES", "LOCALIZE_FILES",
           "FIGURE_FILES", "HTML_FILES", "PATH_FIGURES", "MAPPING_FIGURES", "Column", "COLUMNS",
           "METRICS", "check_metric", "select", "OBJECTIVES", "objective_direction", "UNITS"]

# ---------------------------------------------------------------------------------- the files
#: a run's results (:data:`COLUMNS` reads them): written last, so a folder holding it holds the
#: rest of the run's files
METRICS_FILE = "metrics.json"
#: the status of a sweep job (``completed``, ``failed`` or ``interrupted``) and of a run that
#: failed or was interrupted, with the error
STATUS_FILE = "status.json"
#: the folder of a sweep where its jobs share simulated trajectories
CACHE_DIR = ".cache"
#: an optimising search's trials (Optuna's study), in its sweep folder: their objective, and
#: each trial's parameters, value and the sweep folder and job it ran as
STUDY_FILE = "study.json"

#: files every run writes, with what they hold (figures only with ``output.figures``)
OUTPUT_FILES = {
    "trajectory.npz": "the observations and actions learned from (plus GDS, ground truth)",
    "map.json": "the learned map (states, observation models, counts, split history)",
    "map.graphml": "the map as a graph: arcs where P(x'|x,u) > output.min_prob",
    "states.csv": "step, state after phase 1, final state (and ground-truth place)",
    METRICS_FILE: "entropies, ARI/NMI/purity/compound states, splits, timings, versions, config",
}
#: the file a run learned with ``learner.motion.mode=robot`` adds: the cells a walk is placed on
ROBOT_FILES = {
    "robot_map.npz": "the robot mode's metric map: cells, their scans and successors, places "
                     "(topomap.core.motion.robot_io.load_robot_map)",
}
#: files a ``task=localize`` run writes
LOCALIZE_FILES = {
    "states.csv": "step, filtered state (argmax of the belief), Viterbi state (and place)",
    "beliefs.npz": "beliefs: (T, S) belief over the map's states at every step (past only)",
    METRICS_FILE: "log-likelihood, ARI/NMI/purity of both state sequences, config, versions",
}
FIGURE_FILES = {
    "fig_states.png": "observation points coloured by state after clustering, after splitting and "
                      "(with refine) after the refinement, or a continuous log's places "
                      "(the paper's Fig. 4, right)",
    "fig_split.png": "a compound state before and after its split, with transition tables (Figs. 5-6)",
    "fig_map.png": "the learned map at the states' mean positions (without positions, or states "
                   "scattered over the floor: at a graph layout), arcs where P > min_prob and "
                   "self-loops (a map that mostly stays: the moves between states) (Fig. 7)",
    "fig_entropy.png": "H(u|x), H(x'|x,u) and their sum after each split (and after the "
                       "refinement, or a continuous log's places)",
}
#: the figure a run whose steps have positions but no discrete places adds (the arena, a log)
PATH_FIGURES = {
    "fig_path.png": "the path learned from, coloured by time, over the floor plan",
}
#: the interactive map every run writes with its figures (``output.figures``)
HTML_FILES = {
    "map.html": "the learned map to zoom, pan and hover (states, visits, places, transitions); "
                "one self-contained file, plotly's JavaScript inlined",
}
#: the figure a run that maps while exploring (``data.update_every`` > 0) adds
MAPPING_FIGURES = {
    "fig_mapping.png": "mapping while exploring: the map's ARI against the steps taken",
}


# ---------------------------------------------------------------------------------- the numbers
def select(data: dict, place: str) -> Any:
    """``data[a][b]...`` for ``place`` ``"a.b..."`` (:meth:`omegaconf.OmegaConf.select`, on the
    entry ``a`` alone: a run's numbers sit in small entries of a large file); None where a level
    is missing or is no mapping."""
    head = place.partition(".")[0]
    if not isinstance(data, dict) or head not in data:
        return None
    tree = OmegaConf.create({head: data[head]}, flags={"allow_objects": True})
    try:
        return OmegaConf.select(tree, place, default=None, throw_on_resolution_failure=False)
    except OmegaConfBaseException:  # a level that is a list
        return None


@dataclass(frozen=True)
class Column:
    """One number of a run, by name: a numeric column of a sweep's ``summary.csv``.

    name : str
        The column's name (the CSV header, ``--metric``, ``sweep_report.metric``, a logger's
        metric).
    place : str or tuple of str
        Where the value is in the run's ``file``: keys joined by dots
        (``"ground_truth.final.ari"``); several places are summed (None unless all are there).
    label : str
        What the value is, with its unit: the printed table's and the figures' label.
    better : "max", "min" or None
        Which value is the best job's; None for a column no job is best at (the state counts).
    file : str
        :data:`METRICS_FILE` (written by a completed run) or :data:`STATUS_FILE` (by any job
        that ended).
    """

    name: str
    place: str | tuple[str, ...]
    label: str
    better: str | None = None
    file: str = METRICS_FILE

    def read(self, data: dict) -> Any:
        """The column's value in ``data`` (what its ``file`` holds): None where it is missing."""
        places = (self.place,) if isinstance(self.place, str) else self.place
        values = [select(data, place) for place in places]
        if any(v is None for v in values):
            return None
        return values[0] if len(values) == 1 else functools.reduce(operator.add, values)


#: the numbers of a run, in the order of ``summary.csv``
COLUMNS = (
    Column("n_states_phase1", "n_states.phase1", "states after phase 1"),
    Column("n_states", "n_states.final", "final states"),
    Column("ari", "ground_truth.final.ari", "final ARI", "max"),
    Column("nmi", "ground_truth.final.nmi", "final NMI", "max"),
    Column("purity", "ground_truth.final.purity", "final purity", "max"),
    Column("compound_states", "ground_truth.final.compound_states", "final compound states",
           "min"),
    Column("ari_phase1", "ground_truth.phase1.ari", "phase-1 ARI", "max"),
    Column("nmi_phase1", "ground_truth.phase1.nmi", "phase-1 NMI", "max"),
    Column("purity_phase1", "ground_truth.phase1.purity", "phase-1 purity", "max"),
    Column("H_o", "entropies.final.H_o", "H(o|x) [bits, differential]"),
    Column("H_u", "entropies.final.H_u", "H(u|x) [bits]", "min"),
    Column("H_x", "entropies.final.H_x", "H(x'|x,u) [bits]", "min"),
    Column("heldout_loglik", "heldout_loglik",
           "held-out log-likelihood per step [nats, a log-density]", "max"),
    Column("pos_error", "position.map.median_error", "median localisation error, held-out [m]",
           "min"),
    Column("pos_error_p90", "position.map.p90_error",
           "90th-percentile localisation error, held-out [m]", "min"),
    Column("wrong_region", "position.map.wrong_region", "held-out steps placed in the wrong "
           "region (share)", "min"),
    Column("ceiling_error", "position.ceiling.median_error",
           "median error of the true places (the ceiling) [m]"),
    Column("ceiling_wrong_region", "position.ceiling.wrong_region",
           "wrong-region share of the true places (the ceiling)"),
    Column("views_error", "position.kmeans_views.median_error",
           "median error of K-means on the views [m]"),
    Column("views_wrong_region", "position.kmeans_views.wrong_region",
           "wrong-region share of K-means on the views"),
    Column("positions_error", "position.kmeans_positions.median_error",
           "median error of K-means on the true positions [m]"),
    Column("nav_success", "navigation.success_rate", "navigation success rate", "max"),
    Column("nav_path_ratio", "navigation.path_ratio", "navigation path length / shortest", "min"),
    Column("fit_time", ("timings.phase1", "timings.phase2"), "fit time [s]", "min"),
    Column("data_time", "timings.data", "data time [s]", "min"),
    Column("job_time", "job_time", "job time [s]", "min", file=STATUS_FILE),
)
#: the columns by name
METRICS = {c.name: c for c in COLUMNS}


def check_metric(metric: str, param: str = "metric") -> Column:
    """The column named ``metric``; a :class:`ParameterError` naming ``param`` if none is."""
    if metric not in METRICS:
        raise ParameterError(param, f"={metric!r} is not a summary column; choose one of "
                                    f"{', '.join(METRICS)}")
    return METRICS[metric]


#: what a run can return to an optimising sweeper (the config key ``objective``): each is a
#: column of :data:`COLUMNS` (where its value is, which way is better: the sweeper's
#: ``direction``), with what a run needs to have a value for it
OBJECTIVES = {
    "heldout_loglik": "held-out data: data.heldout_steps > 0 (data=simulate; default: "
                      "data.n_steps) or data.heldout_path (data=file, data=rosbag)",
    "ari": "ground truth (the places of a simulated world, or a recording with them)",
}


def objective_direction(name: str) -> str:
    """The ``direction`` a sweeper optimising the objective ``name`` needs: ``maximize`` or
    ``minimize``."""
    return "maximize" if METRICS[name].better == "max" else "minimize"


#: what the less obvious numbers of metrics.json measure
UNITS = {
    "H_o": "bits; a differential entropy of the Gaussian observation models (continuous "
           "observations), so it can be negative",
    "H_u, H_x": "bits",
    "heldout_loglik": "nats per step; a log-density of continuous observations, so it can be "
                      "positive",
    "loglik": "nats per step (task=localize); a log-density, like heldout_loglik",
    "position": "median_error, p90_error: metres between where a held-out step is placed (its "
                "state's mean training position) and where it was; wrong_region: a share of the "
                "held-out steps; coverage: each region's share of the training and of the "
                "held-out steps, and heldout_unvisited, the share of held-out steps in regions "
                "the training walk never entered",
}
