"""What sits between an agent and the environment and reads the task's internals.

- `residual`: `ResidualSetpoint`, an agent's output as a
  set-point around the target;
- `shield`: `Shield`, a model-predictive safety shield for any
  policy of the single environment (and any robot of a vector env's task).
"""

from scara_gym.wrappers.residual import ResidualSetpoint
from scara_gym.wrappers.shield import Shield, hold_and_climb

__all__ = ["ResidualSetpoint", "Shield", "hold_and_climb"]
