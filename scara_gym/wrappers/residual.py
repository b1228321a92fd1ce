"""A residual set-point around the target: the action map of the engineered agents (numpy
only, so that any agent, SB3's or a single-file torch one, acts through the same map).

The agent's output r in [-1, 1]^3 becomes the set-point  target + residual_scale * deadzone(r),
deadzone(r) = sign(r) max(|r| - z, 0) / (1 - z), with the target read from the observation
(q + target error). Every |r| < z commands the target exactly, which the 0.001 success band
needs (a plain linear map would ask the policy's mean for 4e-4 precision), while the agent
can still hold an axis back by up to residual_scale.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from scara_gym.envs.task import OBSERVATION_LAYOUT

Q, TARGET_ERROR = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["target_error"]


class ResidualSetpoint:
    """Maps agent outputs r to environment actions, for a batch of raw observations.

    The set-point is target + residual_scale * deadzone(r): the agent acts around the target.

    Args:
        env: the environment the actions are for (its unwrapped ScaraEnv or vector env; a
            wrapped one is unwrapped): its set-point maps (``setpoint_action``, ``pd_setpoint``).
        residual_scale (sequence of 3 floats): the largest offset from the target per axis
            [rad, rad, m], each >= 0.
        deadzone: the share of r's range, in [0, 1), mapped to the target itself.
    """

    def __init__(self, env: gym.Env, residual_scale, deadzone: float = 0.0) -> None:
        if not 0.0 <= deadzone < 1.0:
            raise ValueError(f"residual_deadzone must be in [0, 1), got {deadzone!r}")
        scale = np.asarray(residual_scale, dtype=float)
        if scale.shape != (3,) or not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise ValueError(f"residual_scale must be 3 finite numbers >= 0 [rad, rad, m], got {residual_scale!r}")
        self.env = env.unwrapped
        self.scale = scale
        self.deadzone = float(deadzone)

    def __call__(self, obs: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The set-point action of residual actions r in [-1, 1] on observations (batched or one)."""
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        r = np.clip(np.atleast_2d(np.asarray(r, dtype=float)), -1.0, 1.0)
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        shaped = np.sign(r) * np.maximum(np.abs(r) - self.deadzone, 0.0) / (1.0 - self.deadzone)
        setpoint = target + self.scale * shaped
        return self.env.setpoint_action(obs, setpoint)

    def agent_actions(self, obs: np.ndarray, env_actions: np.ndarray, saturation_margin: float = 0.2) -> np.ndarray:
        """Outputs r in [-1, 1] that this map turns into (about) the given environment actions on
        raw observations: demonstrations in the agent's own action space. In "voltage" mode the
        set-point is the one for which the held PD law gives the voltage (a saturated voltage,
        |action| >= 0.999, asks ``saturation_margin`` more, so that it stays saturated); r is
        clipped where the set-point lies beyond target +- residual_scale.
        """
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        env_actions = np.atleast_2d(np.asarray(env_actions, dtype=float))
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        if self.env.control_mode == "pd":
            setpoint = self.env.action_to_setpoint(env_actions)
        else:
            setpoint = self.env.pd_setpoint(obs, env_actions, saturation_margin)
        with np.errstate(divide="ignore", invalid="ignore"):
            shaped = np.where(self.scale > 0, (setpoint - target) / self.scale, 0.0)
        r = np.sign(shaped) * (self.deadzone + (1.0 - self.deadzone) * np.abs(shaped))
        return np.clip(np.where(shaped == 0.0, 0.0, r), -1.0, 1.0)
