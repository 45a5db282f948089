"""The learner's methods that apply its learned map (``map_``) to new sequences: scikit-learn's
``predict`` and ``score`` and hmmlearn's ``predict_proba``, ``score_samples``, ``decode`` and
``sample``, each the :class:`~topomap.core.map.model.TopologicalMap` method of the same name;
and hmmlearn's names of a fitted model (``n_components``, ``startprob_``, ``transmat_``,
``means_``, ``covars_``) as read-only views of the map; and the fit conveniences ``fit_trajectory`` and
``fit_predict``.

``predict`` and ``score`` take the robot's ``odometry`` as ``fit`` does, checked
(:func:`topomap.core.motion.inputs.check_odometry`): a map localises a walk from its views and
actions alone, and the decoding does not use the odometry -- except ``predict`` on a map learned
with ``motion="robot"``, which places the walk by its own odometry and needs it
(:func:`topomap.core.motion.robot_fit.predict_robot`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from sklearn.utils.validation import check_is_fitted

from .motion.inputs import check_odometry
from .motion.robot_fit import predict_robot

__all__ = ["MapMethods"]


def _read_only(a: np.ndarray) -> np.ndarray:
    """A view of ``a`` that cannot be written (the map never changes)."""
    view = a.view()
    view.flags.writeable = False
    return view


class MapMethods:
    """What :class:`topomap.MapLearner` does with its ``map_``; each method raises
    scikit-learn's ``NotFittedError`` before :meth:`fit` (or :meth:`partial_fit`).

    ``actions=None`` (hmmlearn's ``predict(X)``, scikit-learn's ``score(X)``): a sequence of
    observations alone is decoded on the map with its actions summed out, whose transitions are
    :attr:`TopologicalMap.marginal_transition_probs
    <topomap.core.map.model.TopologicalMap.marginal_transition_probs>`; its likelihood is that
    of the observations, ``P(o) = sum_u P(o, u)``.

    hmmlearn's names, read-only views of ``map_`` (S states, A actions, D features):

    * ``n_components``: S, the number of states learned (a parameter in hmmlearn; here the
      parameter is ``n_states``, which the map may not keep: ``"auto"``, a free refinement);
    * ``startprob_`` (S,): the share of steps in each state, which every episode starts from
      when decoding (a robot's walk starts anywhere);
    * ``transmat_`` (A, S, S): ``transmat_[a, i, j] = P(x'=j | x=i, u=a)``, one hmmlearn
      ``transmat_`` per action (the action chooses the matrix); with the actions summed out it is
      ``map_.marginal_transition_probs`` (S, S), hmmlearn's own;
    * ``means_`` (S, D) and ``covars_`` (S, D, D): each state's Gaussian, tied between the states
      split from one symbol; ``covars_`` holds full matrices whatever ``covariance_type``, as
      hmmlearn's ``covars_`` does (``map_.covariances`` keeps the (S, D) variances of ``"diag"``).
    """

    def _fitted_map(self):
        check_is_fitted(self, "map_")
        return self.map_

    @property
    def n_components(self) -> int:
        """S, the number of states of the learned map (hmmlearn's name)."""
        return self._fitted_map().n_states

    @property
    def startprob_(self) -> np.ndarray:
        """(S,) the share of steps in each state: where an episode starts when decoding."""
        return _read_only(self._fitted_map().state_probs)

    @property
    def transmat_(self) -> np.ndarray:
        """(A, S, S) ``P(x'|x, u)``, one (S, S) matrix per action, rows summing to 1."""
        return _read_only(np.moveaxis(self._fitted_map().transition_probs, 1, 0))

    @property
    def means_(self) -> np.ndarray:
        """(S, D) the mean of each state's Gaussian observation model."""
        return _read_only(self._fitted_map().means)

    @property
    def covars_(self) -> np.ndarray:
        """(S, D, D) the covariance of each state's Gaussian, as full matrices."""
        cov = self._fitted_map().covariances
        if cov.ndim == 2:  # "diag": the variances on the diagonals
            full = np.zeros(cov.shape + cov.shape[-1:])
            full[:, np.arange(cov.shape[1]), np.arange(cov.shape[1])] = cov
            cov = full
        return _read_only(cov)

    def predict(self, observations: ArrayLike, actions: ArrayLike | None = None,
                gds: ArrayLike | None = None, lengths: ArrayLike | None = None, *,
                odometry: ArrayLike | None = None) -> np.ndarray:
        """The most likely state of every step of a new sequence (Viterbi on the learned map:
        :meth:`TopologicalMap.predict <topomap.core.map.model.TopologicalMap.predict>`);
        without ``actions``, on the map with its actions summed out; ``odometry`` is checked,
        not used (see the module docstring) -- after a fit with ``motion="robot"`` it is
        required, and each step gets the place the robot route puts it in (a map whose odometry
        was read from the scans, ``motion_info_["odometry_from"] == "scans"``: without it, the
        walk's own is read from its scans).
        Raises scikit-learn's ``NotFittedError`` before :meth:`fit` (or :meth:`partial_fit`)."""
        check_is_fitted(self, "map_")
        robot = getattr(self, "robot_map_", None)
        if robot is not None:
            return predict_robot(robot, observations, lengths, odometry,
                                 (getattr(self, "motion_info_", None) or {}).get(
                                     "odometry_from") == "scans")
        self._check_odometry(odometry, observations, lengths)
        return self.map_.predict(observations, actions, gds=gds, lengths=lengths)

    def score(self, observations: ArrayLike, actions: ArrayLike | None = None,
              gds: ArrayLike | None = None, lengths: ArrayLike | None = None, *,
              odometry: ArrayLike | None = None) -> float:
        """Mean log-likelihood per step (nats; a log-density) of a new sequence under the learned
        map (:meth:`TopologicalMap.score <topomap.core.map.model.TopologicalMap.score>`);
        without ``actions``, that of the observations alone; ``odometry`` is checked, not used.
        Raises scikit-learn's ``NotFittedError`` before :meth:`fit` (or :meth:`partial_fit`)."""
        check_is_fitted(self, "map_")
        self._check_odometry(odometry, observations, lengths)
        return self.map_.score(observations, actions, gds=gds, lengths=lengths)

    @staticmethod
    def _check_odometry(odometry, observations, lengths) -> None:
        if odometry is not None:
            check_odometry(odometry, len(observations), lengths)

    def predict_proba(self, observations: ArrayLike, actions: ArrayLike | None = None,
                      gds: ArrayLike | None = None,
                      lengths: ArrayLike | None = None) -> np.ndarray:
        """(T, S) posterior of every state at every step given its whole episode
        (forward-backward: :meth:`TopologicalMap.predict_proba
        <topomap.core.map.model.TopologicalMap.predict_proba>`), as hmmlearn's."""
        check_is_fitted(self, "map_")
        return self.map_.predict_proba(observations, actions, gds=gds, lengths=lengths)

    def score_samples(self, observations: ArrayLike, actions: ArrayLike | None = None,
                      gds: ArrayLike | None = None,
                      lengths: ArrayLike | None = None) -> tuple[float, np.ndarray]:
        """``(log_prob, posteriors)``: the summed log-likelihood and :meth:`predict_proba` in
        one pass (:meth:`TopologicalMap.score_samples
        <topomap.core.map.model.TopologicalMap.score_samples>`), as hmmlearn's."""
        check_is_fitted(self, "map_")
        return self.map_.score_samples(observations, actions, gds=gds, lengths=lengths)

    def decode(self, observations: ArrayLike, actions: ArrayLike | None = None,
               gds: ArrayLike | None = None, lengths: ArrayLike | None = None, *,
               algorithm: str = "viterbi") -> tuple[float, np.ndarray]:
        """``(log_prob, states)`` by ``algorithm`` ``"viterbi"`` or ``"map"``
        (:meth:`TopologicalMap.decode <topomap.core.map.model.TopologicalMap.decode>`), as
        hmmlearn's."""
        check_is_fitted(self, "map_")
        return self.map_.decode(observations, actions, gds=gds, lengths=lengths,
                                algorithm=algorithm)

    def sample(self, n_samples: int = 1, actions=None, random_state=None, *,
               currstate: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(X, actions, states)``: a walk drawn from the learned map
        (:meth:`TopologicalMap.sample <topomap.core.map.model.TopologicalMap.sample>`);
        ``random_state=None`` uses the learner's ``random_state``, as hmmlearn's."""
        check_is_fitted(self, "map_")
        seed = self.random_state if random_state is None else random_state
        return self.map_.sample(n_samples, actions, seed, currstate=currstate)

    def fit_trajectory(self, traj):
        """Fit on a :class:`topomap.Trajectory`, carrying its names, episode lengths and
        odometry (when it has one)."""
        return self.fit(traj.observations, traj.actions, gds=traj.gds, lengths=traj.lengths,
                        odometry=getattr(traj, "odometry", None), n_actions=traj.n_actions,
                        action_names=traj.action_names, gds_names=traj.gds_names)

    def fit_predict(self, observations, actions, gds=None, lengths=None, **kwargs) -> np.ndarray:
        return self.fit(observations, actions, gds, lengths, **kwargs).labels_
