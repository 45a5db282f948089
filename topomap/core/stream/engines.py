"""Where a streamed fit's per-log work runs: in this process, or on the workers of a Ray
cluster (``pip install "topomap[ray]"``).

An engine has ``map(fn, args_list)``: ``[fn(*args) for args in args_list]`` in order, wherever
the calls run; the first argument of every call is the same log set, sent to each worker once.
The results are combined by the caller in the logs' order, so every engine gives the same
numbers.  What runs on the workers: reading the logs, phase 1's assignment of every step to its
nearest centre, and the moments of the observations; what stays here: the sample K-means is
fitted on, and the split, whose greedy loop is sequential.
"""

from __future__ import annotations

from ..checks import ParameterError

__all__ = ["Local", "RayEngine", "make_engine"]


class Local:
    """Every call in this process, one after the other."""

    name = "local"

    def map(self, fn, shared, args_list):
        return [fn(shared, *args) for args in args_list]


class RayEngine:
    """The calls as Ray tasks (``ray.init`` with ``num_cpus=workers`` when no Ray runtime is
    running in this process; an existing one, e.g. a cluster joined with ``ray.init(address=...)``,
    is used as it is).  ``workers``: the tasks run at once (None: as many as the cluster has
    CPUs)."""

    name = "ray"

    def __init__(self, workers: int | None = None):
        try:
            import ray
        except ImportError:
            raise ParameterError("engine", "='ray' needs Ray: pip install \"topomap[ray]\"") from None
        self._ray = ray
        self.workers = workers
        if not ray.is_initialized():
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     configure_logging=False)

    def map(self, fn, shared, args_list):
        ray = self._ray
        task = ray.remote(num_cpus=1)(fn)
        ref = ray.put(shared)
        return ray.get([task.remote(ref, *args) for args in args_list])


def make_engine(engine, workers: int | None = None):
    """An engine from ``None`` or ``"local"`` (this process), ``"ray"`` (:class:`RayEngine`), or
    an object with the ``map(fn, shared, args_list)`` of :class:`Local`."""
    if engine is None or engine == "local":
        return Local()
    if engine == "ray":
        return RayEngine(workers)
    if callable(getattr(engine, "map", None)) and not isinstance(engine, str):
        return engine
    raise ParameterError("engine", f"={engine!r} is unknown; choose None (this process), 'ray', "
                                   "or an object with map(fn, shared, args_list)")
