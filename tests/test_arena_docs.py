"""The Python examples of docs/continuous.md run as written (with fewer steps)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytest.importorskip("ratinabox")

PAGE = Path(__file__).resolve().parents[1] / "docs" / "continuous.md"
#: sizes shrunk so that the examples run in seconds
SHORTER = {"18_000": "600", "6_000": "200", "n_clusters=32, n_states=64": "n_clusters=4, n_states=8"}


def python_blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", PAGE.read_text(), re.S | re.M)


def test_the_first_walk_runs_and_scores_in_metres():
    code = python_blocks()[0]
    for long, short in SHORTER.items():
        code = code.replace(long, short)
    namespace = {}
    exec(compile(code, str(PAGE), "exec"), namespace)
    scores = namespace["scores"]
    assert set(scores) == {"map", "ceiling", "kmeans_views"}
    for row in scores.values():
        assert 0 <= row["median_error"] <= row["p90_error"] and 0 <= row["wrong_region"] <= 1


def test_the_recorded_path_example_runs(tmp_path, monkeypatch):
    code = python_blocks()[2]
    assert "walk_from" in code
    code = code.replace("world.path_steps - cut", "300").replace("walk_from(0, cut)",
                                                                 "walk_from(0, 300)")
    namespace = {}
    exec(compile("from topomap.worlds.arena import ArenaWorld, RangeFinder\n" + code,
                 str(PAGE), "exec"), namespace)
    assert len(namespace["held"]) == 300 and namespace["world"].path_steps == 73229
