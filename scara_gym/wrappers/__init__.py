"""What sits between an agent and the environment and reads the task's internals.

- `residual`: `ResidualSetpoint`, an agent's output as a
  set-point around the target, and `residual_action`, an env wrapped to act through it
  (`ResidualAction`, `ResidualVectorAction`);
- `shield`: `Shield`, a model-predictive safety shield for any
  policy of the single environment (and any robot of a vector env's task).
"""

from scara_gym.wrappers.residual import (
    ResidualAction,
    ResidualOnPD,
    ResidualSetpoint,
    ResidualVectorAction,
    residual_action,
    residual_setpoint,
)
from scara_gym.wrappers.shield import Shield, hold_and_climb

__all__ = ["ResidualAction", "ResidualOnPD", "ResidualSetpoint", "ResidualVectorAction", "Shield", "hold_and_climb",
           "residual_action", "residual_setpoint"]
