"""What the docs name exists: every ``topomap.`` object a docstring cross-references imports, and
the documented number of BIC clusters is the one a run gives."""

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = re.compile(r":(?:class|func|mod|meth|data|attr|exc):`~?(topomap(?:\.\w+)+)`")


def resolves(name: str) -> bool:
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def test_every_cross_reference_in_a_docstring_resolves():
    pytest.importorskip("minigrid")
    broken = sorted({(path.relative_to(ROOT).as_posix(), name)
                     for path in (ROOT / "topomap").rglob("*.py")
                     for name in REFERENCE.findall(path.read_text()) if not resolves(name)})
    assert broken == []


@pytest.mark.slow
def test_the_docs_give_the_number_of_clusters_bic_picks(make_cfg, tmp_path):
    import json

    from topomap.app.run.experiment import run

    (said,) = re.findall(r"BIC over Gaussian mixtures\s+gives (\d+) clusters",
                         (ROOT / "docs" / "choosing-size.md").read_text())
    run(make_cfg(["clusters=bic", "stop=auto", "output.figures=false",
                  "output.progress=false"]), tmp_path)
    info = json.loads((tmp_path / "map.json").read_text())["info"]
    assert info["n_clusters"] == int(said)
