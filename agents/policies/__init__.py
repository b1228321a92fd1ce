"""Things that act: every policy implements `Policy` (obs in, action out).

- `agents.policies.base`: the protocol and the set-point base class;
- `run_episode`, the one evaluation loop (`scara_gym.benchmark.episodes`, re-exported here);
- `agents.policies.pd`: `PDPolicy`, the classical baseline;
- `agents.policies.heuristic`: `DecHeuristic`, the seed paper's obstacle rule;
- `agents.policies.optimal`: the minimum-time reference (CasADi, an install extra).
- `agents.policies.mpc`, `agents.policies.mpc_rti`: the nonlinear MPC and its real-time iteration
  (CasADi).

Learned policies load with the algorithm that trained them (`agents.algorithms`).
"""

from agents.policies.base import Policy, SetpointPolicy
from agents.policies.heuristic import DecHeuristic, smallest_safe_distance
from agents.policies.pd import PDPolicy
from scara_gym.benchmark.episodes import run_episode

__all__ = ["DecHeuristic", "PDPolicy", "Policy", "SetpointPolicy", "run_episode", "smallest_safe_distance"]
