"""benchmarks/reference_maps.py's account of how two map files differ: only in their floats'
last bits (two machines' numeric kernels) or in their structure."""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from reference_maps import how_they_differ  # noqa: E402


def _json(path, obj):
    path.write_text(json.dumps(obj))
    return path


def test_floats_one_bit_apart_are_named_as_such(tmp_path):
    x = 0.1 + 0.2
    a = {"states": [{"mean": [x, 1.0], "count": 3}], "entropies": [{"H_o": -68.5}]}
    b = {"states": [{"mean": [np.nextafter(x, 1.0), 1.0], "count": 3}],
         "entropies": [{"H_o": -68.5}]}
    text = how_they_differ(_json(tmp_path / "a.json", a), _json(tmp_path / "b.json", b))
    rel = (np.nextafter(x, 1.0) - x) / np.nextafter(x, 1.0)
    assert text == f"floats only: 1 values, largest relative difference {rel:.1e}"


def test_an_integer_or_a_shape_is_structure(tmp_path):
    a = {"states": [{"mean": [0.5, 1.0], "count": 3}]}
    count = {"states": [{"mean": [0.5, 1.0], "count": 4}]}
    shape = {"states": [{"mean": [0.5, 1.0, 2.0], "count": 3}]}
    fa = _json(tmp_path / "a.json", a)
    assert how_they_differ(fa, _json(tmp_path / "c.json", count)) == \
        "structure or integers differ at /states[0]/count"
    assert how_they_differ(fa, _json(tmp_path / "s.json", shape)) == \
        "structure or integers differ at /states[0]/mean"
    assert how_they_differ(fa, _json(tmp_path / "f.json", {"other": 1})).startswith(
        "fields differ")


def test_trajectories_compare_array_by_array(tmp_path):
    P = np.array([[0.0, 1.0], [2.0, 3.0]])
    np.savez(tmp_path / "a.npz", positions=P, actions=np.array([0, 1]))
    np.savez(tmp_path / "b.npz", positions=P * (1 + 1e-12), actions=np.array([0, 1]))
    np.savez(tmp_path / "c.npz", positions=P, actions=np.array([0, 2]))
    assert how_they_differ(tmp_path / "a.npz", tmp_path / "b.npz").startswith(
        "floats only: 3 values")
    assert how_they_differ(tmp_path / "a.npz", tmp_path / "c.npz") == \
        "structure or integers differ at actions"
