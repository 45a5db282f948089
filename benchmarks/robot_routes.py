"""Research routes for robot logs (see bench_robots.py)."""
ROUTES = ()


def route(name, tw, hw, regions, seed, n_clusters, n_states):
    raise ValueError(f"unknown route {name!r}")
