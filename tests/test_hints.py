"""The command line is screened before Hydra composes it: a key of a component that is not
selected names the components that have it, and a misspelt option of a group names the nearest
option, each in one line."""

import subprocess
import sys

import pytest

from topomap.app.compose.command_line import compose


@pytest.mark.parametrize("overrides, message", [
    (["data.path=my.npz"], "data.path belongs to data=file (and data=rosbag), not to "
                           "data=simulate (the default); add data=file"),
    (["+data.path=my.npz"], "data.path belongs to data=file (and data=rosbag)"),
    (["stop=auto", "stop.n_states=40"], "stop.n_states is not a key of stop=auto: it belongs to "
                                        "stop=n_states; leave it out, or choose stop=n_states"),
    (["env=gridrom"], "unknown env=gridrom; did you mean env=gridroom? (the options: arena, "
                      "gridroom, minigrid, office, random_graph)"),
    (["env=office,gridrom"], "unknown env=gridrom; did you mean env=gridroom?"),
    (["experiment=gridrom"], "unknown experiment=gridrom; did you mean experiment=gridroom?"),
])
def test_the_screening_names_what_to_give(overrides, message):
    with pytest.raises(ValueError) as err:
        compose(overrides)
    assert message in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("overrides", [
    ["data=file", "data.path=my.npz"],
    ["experiment=gridroom", "env.n_symbols=3"],  # the preset selects env=gridroom
    ["stop=auto", "stop.patience=2"],
])
def test_a_key_of_the_selected_component_passes(overrides):
    compose(overrides)


@pytest.mark.slow
@pytest.mark.parametrize("args, line", [
    (["data.path=my.npz"], "topomap: error: data.path belongs to data=file (and data=rosbag), "
                           "not to data=simulate (the default); add data=file"),
    (["env=gridrom"], "topomap: error: unknown env=gridrom; did you mean env=gridroom? (the "
                      "options: arena, gridroom, minigrid, office, random_graph)"),
])
def test_the_command_prints_one_line_instead_of_hydras_message(args, line, tmp_path):
    r = subprocess.run([sys.executable, "-m", "topomap", *args], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.splitlines() == [line], r.stderr
    assert not (tmp_path / "outputs").exists()


def test_the_settings_groups_are_typed_config_keys_under_refine():
    """``refine.<group>.<key>``, derived from the refinement's defaults
    (:mod:`topomap.core.refine.settings`): every field, its default, its type."""
    from dataclasses import asdict

    from topomap.core.refine.settings import (CSCGRounds, Growth, HardRounds, Reading,
                                              SoftRounds)

    cfg = compose(["refine=em", "refine.reading.conf_warmup=10", "refine.hard.max_iter=40"])
    assert dict(cfg.refine.reading) == dict(asdict(Reading()), conf_warmup=10)
    assert dict(cfg.refine.hard) == dict(asdict(HardRounds()), max_iter=40)
    assert (dict(cfg.refine.soft), dict(cfg.refine.growth)) == (asdict(SoftRounds()),
                                                                asdict(Growth()))
    cscg = compose(["refine=cscg"]).refine
    assert set(cscg) == {"component", "evidence", "hard", "soft", "reading"}
    assert dict(cscg.hard) == asdict(CSCGRounds()) and dict(cscg.soft) == asdict(SoftRounds())
    with pytest.raises(ValueError, match="did you mean refine.reading.conf_warmup"):
        compose(["refine=em", "refine.reading.warmup=10"])
    with pytest.raises(ValueError, match="^refine.hard.max_iter=abc is not an integer$"):
        compose(["refine=em", "refine.hard.max_iter=abc"])
    with pytest.raises(ValueError, match="^refine.reading.temperature=hot is not a number$"):
        compose(["refine=em", "refine.reading.temperature=hot"])
