"""What a new user trips over: closed configs, help, early checks, clear messages."""

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from topomap import MapLearner, load_trajectory
from topomap.app.run.experiment import run
from topomap.core.data.trajectory import check_sequences

PLUGINS = Path(__file__).resolve().parents[1] / "plugins"
TURNBACK = PLUGINS / "topomap-turnback" / "topomap_turnback.py"


def cli(args, cwd, timeout=120, pythonpath=()):
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1")
    env["PYTHONPATH"] = os.pathsep.join([*map(str, pythonpath), env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-m", "topomap", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


# ---------------------------------------------------------------- 1. unknown keys fail
@pytest.mark.slow
@pytest.mark.parametrize("override, message", [
    ("+typo=1", "unknown config key 'typo'"),
    ("cluster.ns=5", "unknown config key 'cluster.ns'; did you mean clusters.ns?"),
    ("+cluster.ns=5", "unknown config key 'cluster.ns'; did you mean clusters.ns?"),
    ("+clusters.nss=3", "did you mean clusters.ns?"),
    ("+seed=3", "topomap: error: +seed=3: seed is a key of the config already, and + adds only "
                "new ones; drop the +: seed=3\n"),
    ("expriment=gridroom", "did you mean the group experiment (experiment=<option>)?"),
])
def test_a_key_no_schema_declares_fails_with_the_nearest_valid_key(override, message, tmp_path):
    r = cli([override], tmp_path)
    assert r.returncode == 1 and message in r.stderr, r.stderr
    assert r.stderr.count("\n") <= 2 and not (tmp_path / "outputs").exists()


def test_a_key_of_another_component_names_the_components_that_have_it(make_cfg, tmp_path):
    with pytest.raises(ValueError, match=r"^env.n_symbols belongs to env=gridroom \(and "
                                         r"env=random_graph\), not to env=office \(the default\)"):
        run(make_cfg(["+env.n_symbols=3"]), tmp_path)
    assert not any(tmp_path.iterdir())


def test_the_compose_api_refuses_unknown_keys_too(make_cfg):
    with pytest.raises(ValueError, match="did you mean seed"):
        make_cfg(["+sed=3"])


@pytest.mark.parametrize("override, message", [
    ("+seed=3", "+seed=3: seed is a key of the config already, and + adds only new ones; drop "
                "the +: seed=3"),
    ("+clusters.ns=15,20", "+clusters.ns=15,20: clusters.ns is a key of the config already, "
                           "and + adds only new ones; drop the +: clusters.ns=15,20"),
    ("+experiment=gridroom", "+experiment=gridroom: experiment is a group of the config already, "
                             "and + adds only new ones; drop the +: experiment=gridroom"),
    ("+typo=1", "unknown config key 'typo'; the config is typed, so + adds no key (topomap "
                "--help lists the config)"),
    ("expriment=gridroom", "unknown config key 'expriment'; did you mean the group experiment "
                           "(experiment=<option>)?"),
])
def test_hydra_habits_with_plus_are_answered_in_one_line(override, message, make_cfg):
    """Hydra's + adds a key: the config is typed, so a key it has is set without it (Hydra
    refuses +key for a structured config's key too), and an unknown one is named; a misspelt
    group is suggested as the group, not as a key that ends like it (logger.experiment)."""
    with pytest.raises(ValueError) as err:
        make_cfg([override])
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_plus_plus_sets_a_key_either_way(make_cfg):
    assert make_cfg(["++seed=3"]).seed == 3 and make_cfg(["++clusters.ns=15"]).clusters.ns == 15
    with pytest.raises(ValueError, match=r"drop the \+: env.n_symbols=3$"):
        make_cfg(["+env.n_symbols=3", "env=gridroom"])  # a key of the chosen component


@pytest.mark.slow
def test_shell_completion_installs_and_completes_as_hydras(tmp_path):
    """``topomap --shell-completion install=bash`` prints Hydra's bash script for topomap, and
    the completion it asks for (``-sc query=bash``) offers topomap's groups, options and keys."""
    import shutil

    r = cli(["--shell-completion", "install=bash"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert "complete -o nospace -o default -F hydra_bash_completion" in r.stdout
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1", COMP_LINE="topomap env=grid")
    q = subprocess.run([sys.executable, "-m", "topomap", "-sc", "query=bash"], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=120)
    assert q.returncode == 0 and "env=gridroom" in q.stdout.split(), q.stderr
    topomap = shutil.which("topomap")
    if shutil.which("bash") is None or topomap is None:
        return
    script = ('eval "$(topomap --shell-completion install=bash)"; COMP_LINE="topomap stop.n_"; '
              'COMP_POINT=${#COMP_LINE}; COMP_WORDS=(topomap stop.n_); COMP_CWORD=1; '
              'hydra_bash_completion; echo "${COMPREPLY[@]}"')
    path = os.pathsep.join([str(Path(topomap).parent), os.environ.get("PATH", "")])
    b = subprocess.run(["bash", "-c", script], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, env=dict(os.environ, PATH=path))
    assert b.stdout.split() == ["stop.n_states="], b.stdout + b.stderr


def test_a_preset_setting_the_replaced_component_names_the_command_to_give_instead(make_cfg):
    """experiment=gridroom sets stop.n_states; with stop=auto that key has no home.  The message
    spells out the preset's other settings, and that command composes to the same config."""
    with pytest.raises(ValueError, match="experiment=gridroom sets stop.n_states, which "
                                         "stop=auto does not have") as err:
        make_cfg(["experiment=gridroom", "stop=auto"])
    command = str(err.value).split("instead: topomap ")[1].split()
    cfg = make_cfg(command)
    preset = make_cfg(["experiment=gridroom"])
    assert cfg.stop.component == "auto"
    for key in ("env", "refine", "clusters", "data", "noise", "metric", "split"):
        assert cfg[key] == preset[key], key
    make_cfg(["experiment=gridroom", "refine=none"])  # a choice the preset fits still composes


# ---------------------------------------------------------------- 2. a real help text
@pytest.mark.slow
def test_help_is_topomaps_own_and_lists_components_not_schemas(tmp_path):
    r = cli(["--help"], tmp_path)
    assert r.returncode == 0
    assert "powered by Hydra" not in r.stdout and "_schema" not in r.stdout
    assert "Usage:" in r.stdout and "topomap --list-plugins" in r.stdout
    assert "clusters: bic, fixed" in r.stdout
    assert "env: arena, gridroom, minigrid, office" in r.stdout
    assert "sensor: bvc, grid_cells, ovc, place_cells, range" in r.stdout and "actions: compass, turns" in r.stdout
    r = cli(["--help", "plugins=[topomap_gtest]"], tmp_path, pythonpath=[PLUGINS / "topomap-gtest"])
    assert "split: entropy, gtest" in r.stdout and "_schema" not in r.stdout


@pytest.mark.slow
def test_a_plugin_whose_config_folder_cannot_be_found_is_one_clear_line(tmp_path):
    gtest_file = PLUGINS / "topomap-gtest" / "topomap_gtest" / "__init__.py"
    r = cli([f"plugins=[{gtest_file}]"], tmp_path)  # its pkg://topomap_gtest.conf is not importable
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "config folder pkg://topomap_gtest.conf cannot be imported" in r.stderr


@pytest.mark.slow
def test_a_schema_is_not_a_selectable_option(tmp_path):
    r = cli(["clusters=fixed_schema"], tmp_path)
    assert r.returncode == 1
    assert r.stderr == "topomap: error: unknown clusters=fixed_schema (the options: bic, fixed)\n"


# ---------------------------------------------------------------- 5. checked before any work
def test_an_impossible_state_count_fails_before_simulating(make_cfg, tmp_path, monkeypatch):
    from topomap.worlds.office import OfficeWorld

    def simulate(*args, **kwargs):
        raise AssertionError("the world was simulated")

    monkeypatch.setattr(OfficeWorld, "simulate", simulate)
    with pytest.raises(ValueError, match=r"stop.n_states=5 is below the 22 states"):
        run(make_cfg(["stop.n_states=5"]), tmp_path)


def test_check_params_uses_the_cluster_policys_least_count():
    from topomap.core.phase1.clustering import BICClusters

    MapLearner(n_clusters=10, n_states=12).check_params(n_gds=2)
    with pytest.raises(ValueError, match="^n_states=11 is below the 12 states"):
        MapLearner(n_clusters=10, n_states=11).check_params(n_gds=2)
    with pytest.raises(ValueError, match="below the 7 states"):
        MapLearner(clusters=BICClusters(min_ns=7), n_states=6).check_params()


# ---------------------------------------------------------------- 6. where a relative path points
@pytest.mark.slow
def test_a_missing_relative_file_names_the_folder_it_was_looked_for_in(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=rf"missing.npz does not exist \(relative to {tmp_path}\)"):
        load_trajectory("missing.npz")
    r = cli(["data=file", "data.path=missing.npz"], tmp_path)
    assert r.returncode == 1 and f"relative to {tmp_path}" in r.stderr


# ---------------------------------------------------------------- 7. differential entropy, densities
def test_continuous_quantities_say_what_they_are(make_cfg, tmp_path, caplog):
    with caplog.at_level(logging.INFO, logger="topomap"):
        results = run(make_cfg(["data.n_steps=200", "data.heldout_steps=100",
                                "output.figures=false", "output.progress=false",
                                "clusters.ns=8", "stop.n_states=12"]), tmp_path)
    assert "differential entropy" in caplog.text
    units = json.loads((tmp_path / "metrics.json").read_text())["units"]
    assert "differential" in units["H_o"] and "log-density" in units["heldout_loglik"]
    assert results["heldout_loglik"] is not None


# ---------------------------------------------------------------- 10. plugin actions are listed
@pytest.mark.slow
def test_list_plugins_shows_actions_added_by_plugins_with_their_provider(tmp_path):
    r = cli(["--list-plugins", str(TURNBACK)], tmp_path)
    assert r.returncode == 0
    lines = r.stdout.splitlines()
    i = lines.index("actions added to worlds:")
    assert lines[i + 1].split()[:2] == ["turn", "back"] and str(TURNBACK) in lines[i + 1]
    assert "office" in lines[i + 1]


# ---------------------------------------------------------------- 11. 1-D observations
def test_one_dimensional_observations_are_refused_with_a_reshape_hint():
    X = np.arange(10.0)
    u = np.zeros(10, dtype=int)
    with pytest.raises(ValueError, match=r"1-D array of shape \(10,\); reshape it with "
                                         r"observations.reshape\(-1, 1\)"):
        check_sequences(X, u)
    with pytest.raises(ValueError, match="reshape"):
        MapLearner(n_clusters=2, n_states=2).fit(X, u)
    MapLearner(n_clusters=2, n_states=2).fit(X.reshape(-1, 1), u)  # the hint works


def test_a_sweep_cell_without_a_completed_job_says_why():
    from topomap.app.report.columns import no_value

    assert no_value([{"status": "incomplete"}]) == "incomplete"
    assert no_value([{"status": "failed"}, {"status": "incomplete"}]) == "failed/incomplete"
    assert no_value([{"status": "failed"}, {"status": "completed"}]) == ""


def test_too_few_action_names_fail_before_any_work():
    X = np.eye(3)[np.arange(30) % 3]
    with pytest.raises(ValueError, match="action_names has 1 names but n_actions is 3"):
        MapLearner(n_clusters=3, n_states=3).fit(X, np.arange(30) % 3, n_actions=3,
                                                 action_names=["a"])
