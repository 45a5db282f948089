"""The Hydra app: config composition, the CLI end to end, and its error messages."""

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from hydra.errors import ConfigCompositionException
from omegaconf import MISSING, OmegaConf
from omegaconf.errors import ValidationError

from topomap import TopologicalMap, load_trajectory
from topomap.app.run.experiment import run
from topomap.app.run.outputs import numeric_kernels
from topomap.app.results import FIGURE_FILES, OUTPUT_FILES
from topomap.app.compose.registry import Registry

CONF = Path(__file__).resolve().parents[1] / "conf"
PLUGINS = Path(__file__).resolve().parents[1] / "plugins"
BUILTINS = [(kind, name) for kind, name, _, _ in Registry.load(entry_points_group=None).items()]


def options(group):
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


def test_default_config_is_the_papers_experiment(make_cfg):
    cfg = make_cfg()
    assert cfg.env.component == "office" and cfg.env.layout == "paper"
    assert cfg.data.n_steps is None  # the world's own walk: the office's is the paper's 2,000
    assert cfg.clusters.ns == 20 and cfg.stop.n_states == 30
    assert cfg.seed == 0
    preset = make_cfg(["experiment=pricai2002"])
    for key in ("env", "noise", "explorer", "metric", "clusters", "split", "stop", "seed"):
        assert preset[key] == cfg[key], key
    assert preset.data.n_steps == 2000 and {**preset.data, "n_steps": None} == {**cfg.data}


@pytest.mark.parametrize("group, option", BUILTINS)
def test_every_component_is_an_option_that_composes_and_builds(group, option, make_cfg):
    overrides = [f"{group}={option}"]
    if (group, option) == ("data", "file"):
        overrides.append("data.path=x.npz")
    if (group, option) == ("data", "rosbag"):
        overrides += ["data.path=x.bag", "data.observation_topic=/scan", "data.action_topic=/a"]
    cfg = make_cfg(overrides)
    assert cfg[group].component == option
    registry = Registry.load(entry_points_group=None)
    params = dict(cfg[group])
    if group == "env" and option == "minigrid":
        pytest.importorskip("minigrid")
    built = registry.make(group, params)
    if group == "stop":
        built.check(22)


@pytest.mark.parametrize("preset", options("experiment"))
def test_every_experiment_preset_composes(preset, make_cfg):
    cfg = make_cfg([f"experiment={preset}"])
    registry = Registry.load(entry_points_group=None)
    for kind in ("clusters", "split", "stop", "noise", "explorer", "metric"):
        registry.make(kind, cfg[kind])
    assert registry.get("env", cfg.env.component)


def _signature_defaults(factory, kind=None):
    """The factory's parameters and defaults, but those the app passes (its runtime arguments,
    the parts of a component of ``kind``: a world's sensor and actions)."""
    import inspect

    from topomap.app.compose.kinds import parts_of
    from topomap.app.compose.schemas import RUNTIME_ARGS

    skip = set(RUNTIME_ARGS) | set(parts_of(kind) if kind else ())
    return {p.name: (MISSING if p.default is p.empty else p.default)
            for p in inspect.signature(factory).parameters.values()
            if p.name not in skip and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}


def test_every_config_field_matches_its_factory_signature():
    """Built-ins (derived configs) and the example plugins (one derived, two hand-written):
    the config's fields are exactly the factory's parameters, with the same defaults."""
    from topomap.app.compose.schemas import fields_of, schema_of

    plugins = [str(PLUGINS / "topomap-gainratio" / "topomap_gainratio.py"),
               str(PLUGINS / "topomap-gtest" / "topomap_gtest" / "__init__.py")]
    registry = Registry.load(plugins, entry_points_group=None)
    assert not registry.errors
    kinds = set()
    for kind, name, comp, _ in registry.items():
        fields = fields_of(schema_of(comp))
        assert fields.pop("component") == name
        expected = _signature_defaults(comp.load_factory(), kind)
        if "seed" in expected:  # a component's seed follows the run's seed
            assert fields.pop("seed") == "${seed}" and expected.pop("seed") is not MISSING
        # settings given as a dataclass (refine's soft) are a nested config of the same fields
        plain = {k: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v
                 for k, v in fields.items()}
        assert plain == {k: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v
                         for k, v in expected.items()}, (kind, name)
        kinds.add(kind)
    from topomap.app.compose.hookspecs import KINDS

    assert kinds == set(KINDS)


def test_a_hand_written_config_that_disagrees_with_the_factory_is_caught():
    """The check above can fail: a config whose default drifted from the constructor's."""
    from dataclasses import dataclass

    from topomap.app.compose.schemas import fields_of, schema_of
    from topomap.app.compose.hookspecs import Component
    from topomap.core.phase1.clustering import FixedClusters

    @dataclass
    class Drifted:
        component: str = "fixed"
        ns: int = 25  # FixedClusters says 20

    fields = fields_of(schema_of(Component("clusters", "fixed", FixedClusters, Drifted)))
    fields.pop("component")
    assert fields != _signature_defaults(FixedClusters)


def test_learner_config_is_the_learner_signature(make_cfg):
    from topomap import MapLearner

    cfg = make_cfg()
    params = MapLearner().get_params()
    keys = ("covariance_type", "reg_covar", "n_init", "phase1", "sample_size", "refined_size",
            "motion", "heading", "window", "refit_every")
    learner = OmegaConf.to_container(cfg.learner)
    motion = dataclasses.asdict(params["motion"])
    motion["places"]["gates"] = list(params["motion"].places.gates)
    assert learner == {k: motion if k == "motion" else params[k] for k in keys}


@pytest.mark.parametrize("override, message", [
    ("clusters.ns=abc", "clusters.ns=abc is not an integer"),
    ("clusters.nss=3", "unknown config key 'clusters.nss'; did you mean clusters.ns?"),
    ("stop.n_states=1.5", "stop.n_states=1.5 is not an integer"),
    ("env.view_rnage=2", "unknown config key 'env.view_rnage'; did you mean env.view_range?"),
])
def test_typed_config_rejects_bad_values(override, message, make_cfg):
    with pytest.raises((ConfigCompositionException, ValueError)) as info:
        make_cfg([override])
    assert message in str(info.value.__cause__ or info.value)


def test_composed_config_stays_typed(make_cfg):
    cfg = make_cfg()
    with pytest.raises(ValidationError):
        cfg.clusters.ns = "abc"


def small(make_cfg, overrides=()):
    data = [] if "data=file" in overrides else ["data.n_steps=300"]
    return make_cfg([*data, "clusters.ns=8", "stop.n_states=12", "output.progress=false",
                     *overrides])


def test_run_in_process_writes_every_output(tmp_path, make_cfg):
    results = run(small(make_cfg), tmp_path)
    for name in [*OUTPUT_FILES, *FIGURE_FILES]:
        assert (tmp_path / name).is_file(), name
    m = TopologicalMap.load(tmp_path / "map.json")
    assert m.n_states == 12 == results["n_states"]["final"]
    assert results["n_states"]["phase1"] == 8 + 2  # ns symbols + 2 GDS
    traj = load_trajectory(tmp_path / "trajectory.npz")
    assert len(traj) == 300 and traj.places is not None and traj.positions.shape == (300, 2)
    states = np.loadtxt(tmp_path / "states.csv", delimiter=",", skiprows=1, dtype=int)
    assert states.shape == (300, 4) and np.array_equal(states[:, 0], np.arange(300))
    assert np.array_equal(states[:, 3], traj.places)
    assert np.array_equal(np.bincount(states[:, 2], minlength=12), m.state_counts)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    for stage in ("phase1", "final"):
        assert set(metrics["ground_truth"][stage]) >= {"ari", "nmi", "purity", "compound_states"}
        assert set(metrics["entropies"][stage]) >= {"H_o", "H_u", "H_x"}
    assert len(metrics["split_history"]) == 2 and metrics["config"]["clusters"]["ns"] == 8
    assert metrics["versions"]["numpy"] == np.__version__
    assert metrics["versions"]["numeric_kernels"] == numeric_kernels()
    G = nx.read_graphml(tmp_path / "map.graphml")
    assert G.number_of_nodes() == 12
    for png in FIGURE_FILES:
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_same_config_and_seed_same_map_bytes(tmp_path, make_cfg):
    run(small(make_cfg), tmp_path / "a")
    run(small(make_cfg), tmp_path / "b")
    run(small(make_cfg, ["seed=1"]), tmp_path / "c")
    a, b, c = ((tmp_path / d / "map.json").read_bytes() for d in "abc")
    assert a == b and a != c


def test_data_file_learns_from_a_recording_without_simulating(tmp_path, make_cfg):
    run(small(make_cfg), tmp_path / "sim")
    cfg = small(make_cfg, ["data=file", f"data.path={tmp_path / 'sim' / 'trajectory.npz'}"])
    results = run(cfg, tmp_path / "file")
    sim = json.loads((tmp_path / "sim" / "metrics.json").read_text())
    assert results["ground_truth"]["final"] == sim["ground_truth"]["final"]
    assert (tmp_path / "file" / "map.json").read_bytes() == (tmp_path / "sim" / "map.json").read_bytes()


def test_bad_settings_fail_before_any_output(tmp_path, make_cfg):
    with pytest.raises(ValueError, match="stop.n_states=5 is below the 10 states"):
        run(small(make_cfg, ["stop.n_states=5"]), tmp_path / "a")
    with pytest.raises(ValueError, match="does not exist"):
        run(small(make_cfg, ["data=file", "data.path=nope.npz"]), tmp_path / "b")
    with pytest.raises(ValueError, match="clusters=fixed: clusters.ns must be a positive integer"):
        run(small(make_cfg, ["clusters.ns=0"]), tmp_path / "c")
    with pytest.raises(ValueError, match="stop=auto: stop.patience must be a positive integer"):
        run(make_cfg(["data.n_steps=300", "stop=auto", "stop.patience=0"]), tmp_path / "d")
    with pytest.raises(ValueError, match="^learner.reg_covar must be a positive number"):
        run(small(make_cfg, ["learner.reg_covar=0"]), tmp_path / "e")
    assert not any(tmp_path.iterdir())


def test_the_cores_errors_found_while_learning_name_the_config_keys(tmp_path, make_cfg):
    """The core names its own parameters (``ns``, ``method``); a run names the config keys."""
    cfg = small(make_cfg, ["env=gridroom", "env.n_symbols=4", "noise=none", "clusters.ns=5"])
    with pytest.raises(ValueError, match="^clusters.ns=5 is more than the 4 distinct observations"):
        run(cfg, tmp_path / "a")
    with pytest.raises(ValueError, match="^learner.phase1='fast' is unknown"):
        run(small(make_cfg, ["learner.phase1=fast"]), tmp_path / "b")
    assert not any(tmp_path.iterdir())


def cli(args, cwd):
    return subprocess.run([sys.executable, "-m", "topomap", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


@pytest.mark.slow
def test_cli_end_to_end(tmp_path):
    r = cli(["data.n_steps=250", "clusters.ns=8", "stop.n_states=11"], tmp_path)
    assert r.returncode == 0, r.stderr
    (run_dir,) = (tmp_path / "outputs" / "runs").glob("*/*")
    for name in [*OUTPUT_FILES, *FIGURE_FILES]:
        assert (run_dir / name).stat().st_size > 0, name
    assert "11 states" in r.stdout and "ARI" in r.stdout and str(run_dir.name) in r.stdout
    assert json.loads((run_dir / "metrics.json").read_text())["config"]["data"]["n_steps"] == 250


@pytest.mark.slow
def test_cli_errors_are_one_clear_line(tmp_path):
    r = cli(["clusters.ns=abc"], tmp_path)
    assert r.returncode == 1
    assert r.stderr == "topomap: error: clusters.ns=abc is not an integer\n"
    r = cli(["data=file", "data.path=missing.csv"], tmp_path)
    assert r.returncode == 1
    assert "topomap: error: trajectory file missing.csv does not exist" in r.stderr
    assert "Traceback" not in r.stderr
    r = cli(["split=nope"], tmp_path)
    assert r.returncode == 1
    assert r.stderr == "topomap: error: unknown split=nope (the options: entropy)\n"


def test_every_config_folder_is_packaged():
    import tomllib

    meta = tomllib.loads((CONF.parent / "pyproject.toml").read_text())
    packages = set(meta["tool"]["setuptools"]["packages"])
    for folder in [p for p in CONF.rglob("*") if p.is_dir() and p.name != "__pycache__"]:
        name = "topomap.conf." + ".".join(folder.relative_to(CONF).parts)
        assert name in packages, f"{name} is missing from [tool.setuptools] packages"


def test_the_rosbag_data_options_are_read_rosbags_own():
    """``data=rosbag`` takes every option of :func:`topomap.read_rosbag` (but ``action_rule``, a
    callable), with read_rosbag's defaults, beside ``path`` and ``heldout_path``."""
    import inspect

    from topomap import read_rosbag
    from topomap.app.compose.schemas import fields_of, schema_of

    fields = fields_of(schema_of(Registry.load(entry_points_group=None).get("data", "rosbag")))
    wanted = {name: p.default for name, p in inspect.signature(read_rosbag).parameters.items()
              if name not in ("path", "action_rule") and p.default is not p.empty}
    assert {k: v for k, v in fields.items() if k in wanted} == wanted
    assert set(fields) == {"component", "path", "heldout_path", "observation_topic",
                           "action_topic", *wanted}


def _kernels_with(**env) -> dict:
    code = ("import json; from topomap.app.run.outputs import numeric_kernels; "
            "print(json.dumps(numeric_kernels()))")
    out = subprocess.run([sys.executable, "-c", code], env={**os.environ, **env},
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)


def test_numeric_kernels_name_what_numpy_and_blas_dispatch_to():
    """The record follows the libraries' own dispatch: a vector extension switched off by
    numpy's variable is missing from ``numpy_simd``, and OpenBLAS told to run its Haswell
    kernels names them -- the two switches that give another machine's continuous walks."""
    kernels = numeric_kernels()
    found, blas = kernels["numpy_simd"], kernels["blas"]
    assert isinstance(found, list) and all(isinstance(f, str) for f in found)
    assert blas and all(isinstance(b, str) for b in blas)
    if found:  # on top of any the environment switches off already
        off = f"{os.environ.get('NPY_DISABLE_CPU_FEATURES', '')} {found[-1]}".strip()
        assert _kernels_with(NPY_DISABLE_CPU_FEATURES=off)["numpy_simd"] == found[:-1]
    if blas[0].startswith("openblas"):
        assert _kernels_with(OPENBLAS_CORETYPE="Haswell")["blas"][0].endswith("Haswell")
