"""One problem, one wording: a bad value gets the same message whatever the value, naming the
config key on the command line and the Python parameter in Python."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.app.run.experiment import run


@pytest.mark.parametrize("key", ["data.n_steps", "clusters.ns", "stop.n_states", "learner.n_init",
                                 "learner.window", "learner.refit_every"])
def test_a_bad_count_gets_one_wording_naming_its_config_key(key, make_cfg, tmp_path):
    messages = []
    for value in (-5, 0):
        with pytest.raises(ValueError) as err:
            run(make_cfg([f"{key}={value}", "output.progress=false"]), tmp_path / str(value))
        messages.append(str(err.value))
    assert messages[0].replace("-5", "<v>") == messages[1].replace("0", "<v>")
    # data.n_steps null is the world's own length (the arena's 18,000, 2,000 elsewhere)
    kind = "a positive integer or None" if key == "data.n_steps" else "a positive integer"
    assert f"{key} must be {kind}, got -5" in messages[0]
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("param, value", [("n_clusters", "20"), ("n_init", 0), ("window", "5")])
def test_python_names_the_parameter(param, value):
    X, u = np.random.default_rng(0).normal(size=(60, 2)), np.zeros(60, dtype=int)
    with pytest.raises(ValueError) as err:
        MapLearner(**{param: value}).fit(X, u)
    assert str(err.value) == f"{param} must be a positive integer, got {value!r}"
