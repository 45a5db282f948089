"""The streamed fit on a local Ray cluster of two workers gives the map of one process."""

import json

import numpy as np
import pytest

from topomap import MapLearner, Trajectory, save_trajectory

from worlds import ring

ray = pytest.importorskip("ray")


@pytest.mark.slow  # starts a Ray cluster (its processes)
def test_two_ray_workers_make_the_map_of_one_process(tmp_path):
    X, u, places = ring(n_steps=3000, n_places=8, aliased=[(1, 4), (2, 6)], seed=5)
    g = np.full(3000, -1)
    g[[10, 1500, 2900]] = [0, 1, 0]
    folder = tmp_path / "logs"
    folder.mkdir()
    for i, (a, b) in enumerate([(0, 700), (700, 1900), (1900, 2400), (2400, 3000)]):
        save_trajectory(Trajectory(X[a:b], u[a:b], gds=g[a:b]), folder / f"log-{i}.npz")
    kw = dict(n_clusters=6, n_states=10, random_state=3)
    one = MapLearner(**kw).fit_stream(folder)
    try:
        two = MapLearner(**kw).fit_stream(folder, engine="ray", workers=2)
    finally:
        ray.shutdown()
    assert two.stream_info_["engine"] == "ray"
    assert np.array_equal(one.labels_, two.labels_)
    assert json.dumps(one.map_.to_dict()) == json.dumps(two.map_.to_dict())
