"""Plugins: discovery (entry points, config list), the example plugins' effects, error reports."""

import inspect
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from topomap import Trajectory, save_trajectory
from topomap.app.compose.hookspecs import TopomapSpecs
from topomap.app.compose.registry import Registry

ROOT = Path(__file__).resolve().parents[1]
PLUGINS = ROOT / "plugins"
TURNBACK = PLUGINS / "topomap-turnback" / "topomap_turnback.py"


def cli(args, cwd, pythonpath=(), autoload=False):
    """Run ``topomap args`` in ``cwd``; ``autoload`` lets it load installed (entry-point) plugins."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([*map(str, pythonpath), env.get("PYTHONPATH", "")])
    env.pop("TOPOMAP_DISABLE_PLUGIN_AUTOLOAD", None)
    if not autoload:
        env["TOPOMAP_DISABLE_PLUGIN_AUTOLOAD"] = "1"
    return subprocess.run([sys.executable, "-m", "topomap", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def run_dir(cwd):
    dirs = sorted((cwd / "outputs" / "runs").glob("*/*"))
    assert dirs, "no run folder"
    return dirs[-1]


def fake_install(site: Path, dist: str, entry_points: dict, module_src: Path):
    """Make ``site`` look like site-packages holding an installed distribution with entry points
    in group ``topomap`` (what ``pip install`` of the plugin creates)."""
    info = site / f"{dist}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1.0\n")
    lines = "\n".join(f"{k} = {v}" for k, v in entry_points.items())
    (info / "entry_points.txt").write_text(f"[topomap]\n{lines}\n")
    if module_src.is_dir():
        import shutil

        shutil.copytree(module_src, site / module_src.name)
    else:
        (site / module_src.name).write_text(module_src.read_text())


# ---------------------------------------------------------------- a world built for the criteria
def aliased_file(path):
    """Hand-made episodes (one action, 3 steps each) where two aliased states differ.

    State A (symbol 1) is seen 10 times: after P it goes to Q, after R to S -- a perfect split
    worth 1 bit, but on little evidence (G = 2 ln2 * 10 * 1 = 13.9, p ~ 2e-4).
    State B (symbol 6) is seen 1000 times: after C it always goes to D, after E to D or F half
    the time; H = H(3/4, 1/4) = 0.811 bits before, 0.5 after: gain 0.311 bits, but G = 431.
    The entropy criterion splits A first; the G-test splits B first.  Symbols are numbered by
    first appearance: P0 A1 Q2 R3 S4 C5 B6 D7 E8 F9.
    """
    sym = {c: i for i, c in enumerate("PAQRSCBDEF")}
    episodes = 5 * ["PAQ"] + 5 * ["RAS"] + 500 * ["CBD"] + 250 * ["EBD"] + 250 * ["EBF"]
    seq = [sym[c] for ep in episodes for c in ep]
    rng = np.random.default_rng(0)
    X = np.eye(10)[seq] + rng.normal(0, 0.01, (len(seq), 10))
    traj = Trajectory(X, np.zeros(len(seq), dtype=int), lengths=[3] * len(episodes))
    save_trajectory(traj, path)
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return aliased_file(tmp_path_factory.mktemp("data") / "aliased.npz")


def history(cwd):
    return json.loads((run_dir(cwd) / "metrics.json").read_text())["split_history"]


@pytest.mark.slow
def test_gtest_criterion_plugin_changes_which_state_splits(tmp_path, recording):
    base = ["data=file", f"data.path={recording}", "clusters.ns=10", "stop.n_states=11"]
    (tmp_path / "a").mkdir()
    r = cli(base, tmp_path / "a")
    assert r.returncode == 0, r.stderr
    assert [h["state"] for h in history(tmp_path / "a")] == [1]
    # the plugin's package is importable (PYTHONPATH) and listed in the config: its YAML and
    # typed parameters are available in the same command
    (tmp_path / "b").mkdir()
    r = cli([*base, "plugins=[topomap_gtest]", "split=gtest", "split.alpha=0.001"], tmp_path / "b",
            pythonpath=[PLUGINS / "topomap-gtest"])
    assert r.returncode == 0, r.stderr
    assert [h["state"] for h in history(tmp_path / "b")] == [6]
    metrics = json.loads((run_dir(tmp_path / "b") / "metrics.json").read_text())
    assert metrics["providers"]["split"] == "topomap_gtest"
    r = cli([*base, "plugins=[topomap_gtest]", "split=gtest", "split.alpha=abc"], tmp_path / "b",
            pythonpath=[PLUGINS / "topomap-gtest"])
    assert r.returncode == 1 and "split.alpha=abc is not a number" in r.stderr


@pytest.mark.slow
def test_stopping_rule_plugin_from_an_entry_point_changes_the_state_count(tmp_path, recording):
    site = tmp_path / "site"
    fake_install(site, "topomap_gainratio", {"gain_ratio": "topomap_gainratio"},
                 PLUGINS / "topomap-gainratio" / "topomap_gainratio.py")
    base = ["data=file", f"data.path={recording}", "clusters.ns=10"]
    # first split gains 1 bit (A); the next best is B with 0.311 bits
    for ratio, expected in [(0.5, 11), (0.25, 12)]:
        cwd = tmp_path / str(ratio)
        cwd.mkdir()
        r = cli([*base, "stop=gain_ratio", f"stop.ratio={ratio}"], cwd, pythonpath=[site],
                autoload=True)
        assert r.returncode == 0, r.stderr
        m = json.loads((run_dir(cwd) / "metrics.json").read_text())
        assert m["n_states"]["final"] == expected
        assert m["providers"]["stop"] == "gain_ratio"
    r = cli(["--list-plugins"], tmp_path, pythonpath=[site], autoload=True)
    assert r.returncode == 0
    line = next(l for l in r.stdout.splitlines() if l.strip().startswith("gain_ratio"))
    assert "gain_ratio" in line.split()[1]  # provider column: the entry point's name


@pytest.mark.slow
def test_action_plugin_from_a_file_adds_an_action(tmp_path):
    r = cli([f"plugins=[{TURNBACK}]", "data.n_steps=300", "clusters.ns=8", "stop.n_states=12"],
            tmp_path)
    assert r.returncode == 0, r.stderr
    with np.load(run_dir(tmp_path) / "trajectory.npz", allow_pickle=False) as f:
        names = f["action_names"].tolist()
        actions = f["actions"]
    assert names[-1] == "turn back" and len(names) == 18
    assert (actions == 17).any()


@pytest.mark.slow
def test_autoload_switch_keeps_installed_action_plugins_out(tmp_path):
    """An installed action plugin adds its action to the office world; with
    TOPOMAP_DISABLE_PLUGIN_AUTOLOAD=1 the paper's run keeps its 17 actions."""
    site = tmp_path / "site"
    fake_install(site, "topomap_turnback", {"turnback": "topomap_turnback"}, TURNBACK)
    small = ["data.n_steps=200", "data.heldout_steps=0", "clusters.ns=8", "stop.n_states=12",
             "output.figures=false"]
    for autoload, n_actions in [(True, 18), (False, 17)]:
        cwd = tmp_path / str(autoload)
        cwd.mkdir()
        r = cli(small, cwd, pythonpath=[site], autoload=autoload)
        assert r.returncode == 0, r.stderr
        with np.load(run_dir(cwd) / "trajectory.npz", allow_pickle=False) as f:
            assert len(f["action_names"]) == n_actions


def test_cached_trajectory_key_names_the_loaded_plugins(make_cfg):
    from omegaconf import OmegaConf

    from topomap.app.run.data import trajectory_key

    cfg = OmegaConf.to_container(make_cfg(), resolve=True)
    assert trajectory_key(cfg, plugins=["turnback"]) != trajectory_key(cfg)
    assert trajectory_key(cfg, plugins=["turnback"]) == trajectory_key(cfg, plugins=["turnback"])


@pytest.mark.slow
def test_list_plugins_shows_every_kind_and_provider(tmp_path):
    r = cli(["--list-plugins", str(TURNBACK)], tmp_path)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    for kind in ("env:", "noise:", "explorer:", "metric:", "clusters:", "split:", "stop:"):
        assert kind in out
    assert "entropy" in out and "topomap.builtins" in out


# ---------------------------------------------------------------- registry errors
def write_plugin(path: Path, body: str) -> Path:
    path.write_text(textwrap.dedent(body))
    return path


COMPONENT = """
from topomap import Component, hookimpl
from topomap.core.split.criteria import EntropyCriterion

@hookimpl
def topomap_register_components():
    return [Component("split", "{name}", EntropyCriterion)]
"""


def test_two_plugins_with_one_name_is_an_error_naming_both(tmp_path):
    a = write_plugin(tmp_path / "plug_a.py", COMPONENT.format(name="twin"))
    b = write_plugin(tmp_path / "plug_b.py", COMPONENT.format(name="twin"))
    with pytest.raises(ValueError, match=r"'twin' is registered by two plugins: .*plug_a.*plug_b"):
        Registry.load([str(a), str(b)], entry_points_group=None)
    with pytest.raises(ValueError, match="registered by two plugins: 'topomap.builtins'"):
        Registry.load([str(write_plugin(tmp_path / "plug_c.py", COMPONENT.format(name="entropy")))],
                      entry_points_group=None)


OWN_CLASS = """
from topomap import Component, hookimpl
from topomap.core.split.criteria import EntropyCriterion


class {name}(EntropyCriterion):
    pass


@hookimpl
def topomap_register_components():
    return [Component("split", "{name}", {name})]
"""


def test_two_plugin_files_of_one_name_each_load_as_a_module_of_their_own(tmp_path):
    """``a/plug.py`` and ``b/plug.py`` both load, and each one's class is found in the module
    its ``__module__`` names (where pickle and typing look for it)."""
    paths = []
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        paths.append(write_plugin(tmp_path / folder / "plug.py",
                                  OWN_CLASS.format(name=f"from_{folder}")))
    reg = Registry.load([str(p) for p in paths], entry_points_group=None)
    for name in ("from_a", "from_b"):
        factory = reg.get("split", name).factory
        assert getattr(sys.modules[factory.__module__], name, None) is factory


def test_a_broken_plugin_is_reported_and_does_not_hide_the_others(tmp_path):
    bad = write_plugin(tmp_path / "broken.py", "raise RuntimeError('boom')\n")
    good = write_plugin(tmp_path / "good.py", COMPONENT.format(name="mine"))
    reg = Registry.load([str(bad), str(good), "no_such_module_xyz"], entry_points_group=None)
    assert "mine" in reg.names("split")
    errors = [str(e) for e in reg.errors]
    assert any("broken.py" in e and "boom" in e for e in errors)
    assert any("no_such_module_xyz" in e and "ModuleNotFoundError" in e for e in errors)
    with pytest.raises(ValueError, match="split='nope' is not a registered split component; "
                                         "available: entropy, mine; note that plugin"):
        reg.get("split", "nope")


@pytest.mark.slow
def test_a_broken_entry_point_is_reported_by_name(tmp_path):
    site = tmp_path / "site"
    fake_install(site, "brokenplug", {"brokenplug": "brokenplug_mod"},
                 write_plugin(tmp_path / "brokenplug_mod.py", "import nonexistent_dependency\n"))
    r = cli(["--list-plugins"], tmp_path, pythonpath=[site], autoload=True)
    assert r.returncode == 0
    assert "plugin 'brokenplug' (module brokenplug_mod) failed to load" in r.stdout
    assert "entropy" in r.stdout  # the built-ins are still there


def test_builtins_use_the_same_hook_as_plugins():
    reg = Registry.load(entry_points_group=None)
    impls = reg.pm.hook.topomap_register_components.get_hookimpls()
    assert [reg.pm.get_name(i.plugin) for i in impls] == ["topomap.builtins"]
    assert len(list(reg.items())) >= 14


def test_every_hook_is_documented():
    doc = (ROOT / "docs" / "plugins.md").read_text()
    for name, fn in inspect.getmembers(TopomapSpecs, inspect.isfunction):
        assert f"`{name}" in doc, name
        for param in list(inspect.signature(fn).parameters)[1:]:
            assert param in doc, (name, param)


def test_progress_hook_sees_every_split_and_records_metrics(tmp_path, make_cfg):
    from test_app import small

    from topomap.app.run.experiment import run

    plug = write_plugin(tmp_path / "recorder.py", """
        from topomap import hookimpl

        @hookimpl
        def topomap_learner_event(event, info):
            info["metrics"].setdefault("events", []).append(event)
            if event == "split":
                info["metrics"].setdefault("gains", []).append(info["record"]["gain"])
        """)
    results = run(small(make_cfg, [f"plugins=[{plug}]"]), tmp_path / "out")
    saved = json.loads((tmp_path / "out" / "metrics.json").read_text())["plugin_metrics"]
    n = len(results["split_history"])
    assert saved["events"] == ["phase1"] + ["split"] * n + ["done"]
    assert saved["gains"] == [h["gain"] for h in results["split_history"]]


@pytest.mark.slow
def test_pip_installed_plugin_is_found_through_its_entry_point(tmp_path, recording):
    import shutil

    target = tmp_path / "site"
    src = shutil.copytree(PLUGINS / "topomap-gtest", tmp_path / "src")  # pip builds in the source
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target",
                          str(target), str(src)],
                         capture_output=True, text=True, timeout=600)
    assert pip.returncode == 0, pip.stderr
    assert (target / "topomap_gtest" / "conf" / "split" / "gtest.yaml").is_file()
    r = cli(["--list-plugins"], tmp_path, pythonpath=[target], autoload=True)
    assert any(l.split()[:2] == ["gtest", "gtest"] for l in r.stdout.splitlines()), r.stdout
    # no plugins= entry: the entry point and the shipped YAML do it all
    r = cli(["data=file", f"data.path={recording}", "clusters.ns=10", "stop.n_states=11",
             "split=gtest"], tmp_path, pythonpath=[target], autoload=True)
    assert r.returncode == 0, r.stderr
    assert [h["state"] for h in history(tmp_path)] == [6]
    cfg = json.loads((run_dir(tmp_path) / "metrics.json").read_text())["config"]
    assert cfg["split"] == {"component": "gtest", "alpha": 0.01}  # the YAML's default


def test_a_plugin_imports_from_topomap_and_the_old_place_still_serves_with_a_warning():
    import importlib

    import topomap
    from topomap.app.compose import hookspecs

    assert topomap.Component is hookspecs.Component and topomap.hookimpl is hookspecs.hookimpl
    old = importlib.import_module("topomap.app.hookspecs")
    with pytest.warns(FutureWarning, match="from topomap import Component, hookimpl"):
        assert old.Component is hookspecs.Component
