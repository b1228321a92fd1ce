"""Things that act: every policy implements :class:`~agents.policies.base.Policy` (obs in, action out).

- :mod:`~agents.policies.base`: the protocol and the set-point base class;
- :func:`run_episode`, the one evaluation loop (:mod:`scara_gym.benchmark.episodes`, re-exported here);
- :mod:`~agents.policies.pd`: :class:`PDPolicy`, the classical baseline;
- :mod:`~agents.policies.heuristic`: :class:`DecHeuristic`, the seed paper's obstacle rule;
- :mod:`~agents.policies.optimal`: the minimum-time reference (CasADi, an install extra).

Learned policies load with the algorithm that trained them (:mod:`agents.algorithms`).
"""

from agents.policies.base import Policy, SetpointPolicy
from agents.policies.heuristic import DecHeuristic, smallest_safe_distance
from agents.policies.pd import PDPolicy
from scara_gym.benchmark.episodes import run_episode

__all__ = ["DecHeuristic", "PDPolicy", "Policy", "SetpointPolicy", "run_episode", "smallest_safe_distance"]
