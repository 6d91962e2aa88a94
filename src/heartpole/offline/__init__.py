"""Offline RL on HeartPole: Minari datasets, the true values that off-policy evaluation estimates, estimators.

Install with ``pip install heartpole[offline]`` (Minari). ``import heartpole.offline`` needs only NumPy:
Minari is imported when a dataset is written or read, PyTorch when a learner trains.

* [`heartpole.offline.datasets`][heartpole.offline.datasets]: record (``record_dataset``, ``record_standard``) and load
  datasets.
* [`heartpole.offline.recorded`][heartpole.offline.recorded]: the env a dataset was recorded on, as Minari stores it
  (``recover_environment()`` makes it).
* [`true_value`][heartpole.offline.truth.true_value]: a policy's true value, discounted and undiscounted, with 95%
  intervals.
* [`heartpole.offline.ope`][heartpole.offline.ope]: PDIS, WPDIS, FQE and DR (``estimate_all``, ``evaluate_off_policy``).
* [`heartpole.offline.learners`][heartpole.offline.learners]: behaviour cloning and discrete CQL.
"""

from heartpole.offline.behaviour import EpsilonGreedy, Mixture, action_probabilities
from heartpole.offline.trajectories import Trajectories, collect
from heartpole.offline.truth import TrueValue, true_value

__all__ = ["EpsilonGreedy", "Mixture", "Trajectories", "TrueValue", "action_probabilities", "collect", "true_value"]
