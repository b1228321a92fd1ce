"""A residual set-point around the target: the action map of the engineered agents (numpy
only, so that any agent, SB3's or a single-file torch one, acts through the same map).

`ResidualSetpoint` is the map; `residual_action(env, residual_scale, deadzone)` wraps an env
with it, a Gymnasium action wrapper (`ResidualAction`) or its vector twin
(`ResidualVectorAction`), whose action space is the agent's r in [-1, 1]^3: trainers wrap
their env with it, and a policy maps its own output with the same class.

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


class ResidualAction(gym.ActionWrapper):
    """``env`` acting through a ResidualSetpoint: ``step(r)`` applies the set-point action of r on
    the observation the env returned last (the agent's own), so that an agent trains and is
    evaluated in the residual's space with the env's API unchanged.

    Args:
        env: a single environment of the C11 task (a ScaraEnv, wrapped or not).
        residual_scale (sequence of 3 floats): ResidualSetpoint's.
        deadzone: ResidualSetpoint's.
    """

    def __init__(self, env: gym.Env, residual_scale, deadzone: float = 0.0) -> None:
        super().__init__(env)
        self.setpoint = ResidualSetpoint(env, residual_scale, deadzone)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.last_obs: np.ndarray | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """The env's reset; its observation kept for the first step's map."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.last_obs = obs
        return obs, info

    def step(self, action):
        """The env's step with the set-point action of r = ``action``; its observation kept."""
        obs, reward, terminated, truncated, info = self.env.step(self.action(action))
        self.last_obs = obs
        return obs, reward, terminated, truncated, info

    def action(self, action):
        """The set-point action of r on the last observation."""
        if self.last_obs is None:
            raise gym.error.ResetNeeded("ResidualAction: call reset() before step(): the map reads the observation")
        return self.setpoint(self.last_obs, action)[0]


class ResidualVectorAction(gym.vector.VectorActionWrapper):
    """ResidualAction's vector twin: ``step(r)`` applies every robot's set-point action of its r on
    the observations the vector env returned last (with autoreset, those the agent sees next).

    Args:
        env: a vector environment of the C11 task (ScaraVectorEnv, wrapped or not).
        residual_scale (sequence of 3 floats): ResidualSetpoint's.
        deadzone: ResidualSetpoint's.
    """

    def __init__(self, env: gym.vector.VectorEnv, residual_scale, deadzone: float = 0.0) -> None:
        super().__init__(env)
        self.setpoint = ResidualSetpoint(env, residual_scale, deadzone)
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self.last_obs: np.ndarray | None = None

    def reset(self, *, seed=None, options: dict | None = None):
        """The vector env's reset; its observations kept for the first step's map."""
        obs, info = self.env.reset(seed=seed, options=options)
        self.last_obs = obs
        return obs, info

    def step(self, actions):
        """The vector env's step with the set-point actions of r = ``actions``; its observations kept."""
        obs, reward, terminated, truncated, info = self.env.step(self.actions(actions))
        self.last_obs = obs
        return obs, reward, terminated, truncated, info

    def actions(self, actions):
        """Every robot's set-point action of its r on the last observations."""
        if self.last_obs is None:
            raise gym.error.ResetNeeded("ResidualVectorAction: call reset() before step(): the map reads the "
                                        "observations")
        return self.setpoint(self.last_obs, actions)


def residual_action(env, residual_scale, deadzone: float = 0.0):
    """``env`` wrapped to act through the residual set-point: ResidualVectorAction for a
    Gymnasium vector env, ResidualAction for a single one.
    """
    if isinstance(env, gym.vector.VectorEnv):
        return ResidualVectorAction(env, residual_scale, deadzone)
    return ResidualAction(env, residual_scale, deadzone)


class ResidualOnPD:
    """Residual policy learning on the C11 PD law (Johannink et al. 2019, Silver et al. 2018), in
    "voltage" mode: the action is the PD law's voltage towards the target (read from the
    observation) plus residual_scale x r, clipped to [-1, 1]. r = 0 is PD itself; the agent
    learns a correction of its voltages, not a set-point.

    Args:
        env: a "voltage"-mode environment (its unwrapped env's ``pd_action`` gives the PD law's voltages).
        residual_scale (sequence of 3 floats): the largest correction per axis, in the action's
            units (1 = the voltage limit), each >= 0.
    """

    def __init__(self, env: gym.Env, residual_scale) -> None:
        scale = np.asarray(residual_scale, dtype=float)
        if scale.shape != (3,) or not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise ValueError(f"residual_scale must be 3 finite numbers >= 0 [action units], got {residual_scale!r}")
        self.env = env.unwrapped
        if self.env.control_mode != "voltage":
            raise ValueError(f"the residual on PD corrects voltages: it needs control_mode='voltage', the env is in "
                             f"{self.env.control_mode!r} mode")
        self.scale = scale

    def __call__(self, obs: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The voltage actions of residual actions r in [-1, 1] on observations (batched or one)."""
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        r = np.clip(np.atleast_2d(np.asarray(r, dtype=float)), -1.0, 1.0)
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        return np.clip(self.env.pd_action(obs, target) + self.scale * r, -1.0, 1.0)

    def agent_actions(self, obs: np.ndarray, env_actions: np.ndarray) -> np.ndarray:
        """Outputs r in [-1, 1] that this map turns into the given voltage actions on raw
        observations (demonstrations in the agent's own action space): the voltage's difference
        from the PD law's over residual_scale, clipped to [-1, 1] (0 on an axis whose scale is 0).
        """
        obs = np.atleast_2d(np.asarray(obs, dtype=float))
        env_actions = np.atleast_2d(np.asarray(env_actions, dtype=float))
        target = obs[:, Q] + obs[:, TARGET_ERROR]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(self.scale > 0, (env_actions - self.env.pd_action(obs, target)) / self.scale, 0.0)
        return np.clip(r, -1.0, 1.0)


RESIDUAL_ON = ("setpoint", "pd")
"""what a residual acts on: the set-point around the target (ResidualSetpoint), or the PD law's
voltages (ResidualOnPD)"""


def residual_setpoint(env, residual_scale, deadzone: float = 0.0, on: str = "setpoint"):
    """The map a run's settings ask for: a ResidualSetpoint (``on`` "setpoint") or a ResidualOnPD
    (``on`` "pd", no dead zone), or None where ``residual_scale`` is None (the run acts in the
    env's own actions). Trainers and policies build it here alike.
    """
    if on not in RESIDUAL_ON:
        raise ValueError(f"residual_on must be one of {RESIDUAL_ON}, got {on!r}")
    if residual_scale is None:
        return None
    return ResidualSetpoint(env, residual_scale, deadzone) if on == "setpoint" else ResidualOnPD(env, residual_scale)
