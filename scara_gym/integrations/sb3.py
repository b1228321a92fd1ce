"""stable-baselines3 on the native vector environment.

SB3 does not accept Gymnasium vector environments; `SB3VecEnv` presents a
`ScaraVectorEnv` (in "SameStep" autoreset mode) through
SB3's ``VecEnv`` interface: ``terminal_observation``, ``TimeLimit.truncated``,
``is_success`` and Monitor-style ``episode`` statistics (r, l, t) in the infos of
finished episodes, as SB3's own wrappers produce them (so no VecMonitor is needed).
Wrap it in ``VecNormalize`` as usual.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from scara_gym.extras import require

require("stable_baselines3")
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from scara_gym.envs.vector import ScaraVectorEnv
from scara_gym.model import checks
from scara_gym.model.checks import UserError
from scara_gym.registration import ENV_KWARGS, GOAL_ENV_IDS, LATEST_ENV_ID


class SB3VecEnv(VecEnv):
    """``SB3VecEnv(num_envs=8, env_id="Scara-C11-v2", control_mode="pd", ...)``: the robots of a
    registered id (the arguments it registers; default the latest id), further arguments as
    ScaraVectorEnv's over them. ``action_wrapper``: a function that wraps the native vector env
    in a Gymnasium vector action wrapper the agent acts through (e.g.
    ``functools.partial(scara_gym.wrappers.residual_action, residual_scale=..., deadzone=...)``).
    """

    def __init__(self, num_envs: int = 8, env_id: str = LATEST_ENV_ID, *, action_wrapper=None, **kwargs: Any) -> None:
        checks.choice("env_id", env_id, tuple(i for i in ENV_KWARGS if i not in GOAL_ENV_IDS))
        if "autoreset_mode" in kwargs:
            raise UserError("autoreset_mode: SB3VecEnv sets 'SameStep' itself (SB3 reads the final observation "
                            "in the step that ends an episode)")
        self.env_id = env_id
        self.venv = ScaraVectorEnv(num_envs=num_envs, autoreset_mode="SameStep", **{**ENV_KWARGS[env_id], **kwargs})
        # the env the agent's actions go to: the native one, or the wrapper it acts through
        self.acting = self.venv if action_wrapper is None else action_wrapper(self.venv)
        super().__init__(num_envs, self.venv.single_observation_space, self.acting.single_action_space)
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(num_envs)
        self._lengths = np.zeros(num_envs, dtype=np.int64)
        self._started = time.time()

    def reset(self):
        """Start every robot's episode (SB3's VecEnv.reset), with the seeds and options set for it; the observations."""
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else seeds
        obs, info = self.acting.reset(seed=seed)
        self.reset_infos = [{"target": info["target"][i]} for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        self._returns[:] = 0.0
        self._lengths[:] = 0
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Keep the actions for step_wait (SB3's VecEnv API)."""
        self._actions = np.asarray(actions)

    def step_wait(self):
        """Step every robot with the kept actions (SB3's VecEnv API): observations, rewards, dones, infos."""
        obs, reward, terminated, truncated, info = self.acting.step(self._actions)
        dones = terminated | truncated
        self._returns += reward
        self._lengths += 1
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            infos[i] = {
                "terminal_observation": info["final_obs"][i],
                "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                "is_success": bool(info["is_success"][i]),
                "collisions": int(info["collisions"][i]),
                "episode": {"r": float(self._returns[i]), "l": int(self._lengths[i]),
                            "t": round(time.time() - self._started, 6)},
            }
            self._returns[i] = 0.0
            self._lengths[i] = 0
        return obs, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        """Close the native vector env."""
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """An attribute of the native vector env, once per robot asked for (SB3's VecEnv API)."""
        return [getattr(self.venv, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Refused (SB3's VecEnv API): the robots share one configuration; build a new SB3VecEnv instead."""
        raise AttributeError("the robots of a native vector environment share one configuration; "
                             "build a new SB3VecEnv instead of setting attributes")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Call a method of the native vector env, its result once per robot asked for (SB3's VecEnv API)."""
        method = getattr(self.venv, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        """False for every robot: the native vector env has no Gymnasium wrappers (SB3's VecEnv API)."""
        return [False for _ in self._get_indices(indices)]
