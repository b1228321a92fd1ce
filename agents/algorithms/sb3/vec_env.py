"""SB3's side of the residual set-point: a VecEnv wrapper (stable-baselines3 imported here, at the top)."""

from __future__ import annotations

from scara_gym.extras import require

require("stable_baselines3")
from stable_baselines3.common.vec_env import VecEnvWrapper

from scara_gym.wrappers import ResidualSetpoint


class ResidualVecEnv(VecEnvWrapper):
    """The agent's outputs r become the wrapped VecEnv's actions through a ResidualSetpoint."""

    def __init__(self, venv, mapping: ResidualSetpoint) -> None:
        super().__init__(venv)
        self.mapping = mapping
        self.last_obs = None

    def reset(self):
        self.last_obs = self.venv.reset()
        return self.last_obs

    def step_async(self, actions):
        self.venv.step_async(self.mapping(self.last_obs, actions))

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        self.last_obs = obs
        return obs, rewards, dones, infos
