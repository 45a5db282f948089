"""The learner's streamed fit, :meth:`StreamFit.fit_stream` (a base of
:class:`topomap.MapLearner`)."""

from __future__ import annotations

from ..data.logs import CHUNK_STEPS

__all__ = ["StreamFit"]


class StreamFit:
    """:meth:`fit_stream`, the fit of logs larger than memory."""

    def fit_stream(self, logs, *, n_actions=None, action_names=None, gds_names=None,
                   engine=None, workers=None, rosbag=None, chunk_steps=CHUNK_STEPS):
        """Learn the map from logs read in chunks, never all in memory.  Returns ``self``.

        ``logs``: a folder (every ``.npz``, ``.csv``, ``.csv.gz``, ``.bag`` file and ROS 2 bag
        folder in it, in name order), a list of such paths, a list of
        :class:`~topomap.Trajectory`, or a :class:`~topomap.core.data.logs.Logs`; each log is one
        episode (or its own ``lengths``).  ``rosbag``: the :func:`~topomap.read_rosbag` arguments
        for bags (topics, ...).  ``n_actions``, ``action_names`` and ``gds_names`` as in
        :meth:`fit` (names in the logs are made consistent across them).  ``engine``: where
        each log is read and its steps given their symbols -- None (this process) or ``"ray"``
        (a Ray cluster, started on this machine with ``workers`` CPUs unless one is running);
        every engine gives the same map.  ``chunk_steps``: steps read at once.

        The fit is the paper's two phases (phase 1 as ``phase1="full"`` or ``"sample"``; no
        refinement, no ``n_states="auto"``, a metric of each row alone), in about 20 bytes a
        step (:mod:`topomap.core.stream.fit`); ``labels_`` and ``labels_phase1_`` are int16
        (int32 past 32,767 states).  Given the same phase-1 symbols its states are those of
        :meth:`fit` on the logs concatenated with ``lengths``, step for step; the observation
        models differ by rounding only.  ``stream_info_`` says how many logs and steps were
        read, on which engine, and the seconds of the survey, the sample and the assignment.
        """
        from .fit import fit_stream

        return fit_stream(self, logs, n_actions=n_actions, action_names=action_names,
                          gds_names=gds_names, engine=engine, workers=workers, rosbag=rosbag,
                          chunk_steps=chunk_steps)
