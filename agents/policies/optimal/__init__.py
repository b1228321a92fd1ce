"""The optimal reference: the minimum-time voltages the physics allows, by direct collocation.

- the model: `scara_gym.model.symbolic` (the CasADi twin of the compiled dynamics);
- `agents.policies.optimal.transcription`: the two minimum-time problems (held and free
  voltages) and their solver;
- `agents.policies.optimal.solutions`: the shipped solutions;
- `agents.policies.optimal.policy`: `OptimalPolicy` and the reference's replay.
"""

from agents.policies.optimal.policy import (
    OptimalPolicy,
    reference_demonstration,
    reference_snapshots,
    replay,
    replaying,
)
from agents.policies.optimal.solutions import SOLUTIONS, cached_solution
from agents.policies.optimal.transcription import CollocationConfig, Solution, minimum_time, solve

__all__ = ["SOLUTIONS", "CollocationConfig", "OptimalPolicy", "Solution", "cached_solution", "minimum_time",
           "reference_demonstration", "reference_snapshots", "replay", "replaying", "solve"]
