"""What users of such a package expect of it: ``topomap --version``, a changelog recording the
release, ``MapLearner.predict`` / ``score``, a ``py.typed`` marker and type hints on ``fit``."""

import re
import subprocess
import sys
import tomllib
import typing
from pathlib import Path

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError

import topomap
from topomap import MapLearner

ROOT = Path(__file__).resolve().parents[1]


def test_the_version_is_one_everywhere_and_the_changelog_records_it():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["version"] == topomap.__version__
    changelog = (ROOT / "CHANGELOG.md").read_text()
    (latest,) = re.findall(r"^## \[?(\d+\.\d+\.\d+)\]?", changelog, re.MULTILINE)[:1]
    assert latest == topomap.__version__


@pytest.mark.slow
def test_version_prints_topomaps_version(tmp_path):
    r = subprocess.run([sys.executable, "-m", "topomap", "--version"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.startswith(f"topomap {topomap.__version__} (Hydra ")
    assert not (tmp_path / "outputs").exists()


def ring(n_steps=400, seed=0):
    """A ring of 6 places with 3 symbols (each twice): forward and backward moves."""
    rng = np.random.default_rng(seed)
    u = rng.integers(0, 2, n_steps)
    place = np.cumsum(np.where(u == 0, 1, -1)) % 6
    X = (place % 3)[:, None] + rng.normal(0, 0.05, (n_steps, 1))
    return X, u, place


def test_predict_and_score_delegate_to_the_map():
    X, u, _ = ring()
    learner = MapLearner(n_clusters=3, n_states=6, n_init=1).fit(X, u)
    X2, u2, _ = ring(200, seed=3)
    assert np.array_equal(learner.predict(X2, u2), learner.map_.predict(X2, u2))
    assert learner.score(X2, u2) == learner.map_.score(X2, u2)
    lengths = [100, 100]
    assert np.array_equal(learner.predict(X2, u2, lengths=lengths),
                          learner.map_.predict(X2, u2, lengths=lengths))


def test_predict_before_fit_is_not_fitted_error():
    X, u, _ = ring(50)
    for method in (MapLearner().predict, MapLearner().score):
        with pytest.raises(NotFittedError, match="MapLearner"):
            method(X, u)


def test_the_package_is_typed():
    assert (Path(topomap.__file__).parent / "py.typed").is_file()
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in meta["tool"]["setuptools"]["package-data"]["topomap"]
    hints = typing.get_type_hints(MapLearner.fit)
    assert {"observations", "actions", "gds", "lengths", "n_actions", "return"} <= set(hints)


def test_topomap_metrics_is_a_module_of_its_own_and_import_topomap_loads_the_core_alone():
    """``from topomap.metrics import ...`` imports a module of that name (no alias of another
    module planted in ``sys.modules``), and ``import topomap`` loads no app layer."""
    code = ("import sys, topomap\n"
            "from topomap.metrics import adjusted_rand, evaluate\n"
            "from topomap.evaluation import partitions\n"
            "assert topomap.metrics.__name__ == 'topomap.metrics', topomap.metrics.__name__\n"
            "assert adjusted_rand is partitions.adjusted_rand and evaluate is partitions.evaluate\n"
            "assert sys.modules['topomap.evaluation.partitions'] is partitions\n"
            "print(sorted({'hydra', 'pluggy', 'omegaconf'} & set(sys.modules)))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
