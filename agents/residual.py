"""The engineered agents' action map: a residual set-point around the target (numpy only, so
that SB3's agents.ppo and the single-file agents.torch_ppo share it).

The agent's output r in [-1, 1]^3 becomes the set-point  target + residual_scale * deadzone(r),
deadzone(r) = sign(r) max(|r| - z, 0) / (1 - z), with the target read from the observation
(q + target error). Every |r| < z commands the target exactly, which the 0.001 success band
needs (a plain linear map would ask the policy's mean for 4e-4 precision), while the agent
can still hold an axis back by up to residual_scale.
"""

from __future__ import annotations

import numpy as np

from scara_gym.envs import OBSERVATION_LAYOUT, ScaraTask

Q, TARGET_ERROR = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["target_error"]
RATES, CRITICAL = OBSERVATION_LAYOUT["rate"], OBSERVATION_LAYOUT["critical"]


class ResidualSetpoint:
    """Maps agent outputs r to environment actions, for a batch of raw observations."""

    def __init__(self, task: ScaraTask, residual_scale, deadzone: float = 0.0) -> None:
        if not 0.0 <= deadzone < 1.0:
            raise ValueError(f"residual_deadzone must be in [0, 1), got {deadzone!r}")
        scale = np.asarray(residual_scale, dtype=float)
        if scale.shape != (3,) or not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise ValueError(f"residual_scale must be 3 finite numbers >= 0 [rad, rad, m], got {residual_scale!r}")
        self.task = task
        self.scale = scale
        self.deadzone = float(deadzone)

    def __call__(self, obs: np.ndarray, r: np.ndarray) -> np.ndarray:
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        r = np.clip(np.atleast_2d(np.asarray(r, dtype=float)), -1.0, 1.0)
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        shaped = np.sign(r) * np.maximum(np.abs(r) - self.deadzone, 0.0) / (1.0 - self.deadzone)
        setpoint = target + self.scale * shaped
        if self.task.control_mode == "pd":
            return np.clip((setpoint - self.task.setpoint_center) / self.task.setpoint_half, -1.0, 1.0)
        return self.task.pd_action(obs, setpoint)

    def agent_actions(self, obs: np.ndarray, env_actions: np.ndarray, saturation_margin: float = 0.2) -> np.ndarray:
        """Outputs r in [-1, 1] that this map turns into (about) the given environment actions on
        raw observations: demonstrations in the agent's own action space. In "voltage" mode the
        set-point is the one for which the held PD law gives the voltage (a saturated voltage,
        |action| >= 0.999, asks ``saturation_margin`` more, so that it stays saturated); r is
        clipped where the set-point lies beyond target +- residual_scale."""
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        env_actions = np.atleast_2d(np.asarray(env_actions, dtype=float))
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        if self.task.control_mode == "pd":
            setpoint = self.task.action_to_setpoint(env_actions)
        else:
            p = self.task.robot_params[0]
            limit = np.where(obs[:, CRITICAL, None] > 0.5, p["wide_voltage_limit"], p["voltage_limit"])
            boost = np.where(np.abs(env_actions) >= 0.999, 1.0 + saturation_margin, 1.0)
            setpoint = obs[:, Q] + (env_actions * boost * limit + p["d_gain"] * obs[:, RATES]) / p["p_gain"]
        with np.errstate(divide="ignore", invalid="ignore"):
            shaped = np.where(self.scale > 0, (setpoint - target) / self.scale, 0.0)
        r = np.sign(shaped) * (self.deadzone + (1.0 - self.deadzone) * np.abs(shaped))
        return np.clip(np.where(shaped == 0.0, 0.0, r), -1.0, 1.0)
