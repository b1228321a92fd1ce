"""Native vector environment: N robots stepped in one parallel compiled call.

``gym.make_vec("Scara-C11-v0", num_envs=N, vectorization_mode="vector_entry_point")``.
Sub-environment i behaves exactly as ``gym.make("Scara-C11-v0", ...)`` reset with
seed ``seed + i`` (the same compiled control step, bit for bit).

Autoreset: ``autoreset_mode="NextStep"`` (Gymnasium's default): the step after an
episode ends resets that robot and returns its first observation with reward 0,
terminated and truncated False. ``"SameStep"``: the ending step already returns the
reset observation; the final observation and info are in ``info["final_obs"]`` and
``info["final_info"]`` (masked by ``info["_final_obs"]``), as the stable-baselines3
adapter needs.
"""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from scara_gym import layout as L
from scara_gym.envs.core import (
    N_OBS, N_RESULT, R_CLIPPED, R_COLLISIONS, R_REACH_TIME, R_REACHED, R_REWARD, R_STATUS, R_TERMS,
    REWARD_TERMS, robot_step_batch, start_episode,
)
from scara_gym.envs.scara_env import ScaraEnv, check_actions


class ScaraVectorEnv(VectorEnv):
    """N copies of Scara-C11-v0 (same arguments as ScaraEnv), stepped in parallel.

    Extra arguments: num_envs, max_episode_steps (300: the registered time limit),
    autoreset_mode ("NextStep" or "SameStep"). Rendering is not supported in the
    vector environment (render_mode must be None). info holds arrays over the robots:
    is_success, cost, collision, collisions, critical, time, energy, clipped_actions,
    reward_terms (a dict of arrays) and reach_time (masked by ``_reach_time``).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, max_episode_steps: int = 300,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP, **kwargs) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer)) \
                or max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be an integer >= 1, got {max_episode_steps!r}")
        try:
            autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(f"autoreset_mode must be 'NextStep' or 'SameStep', got {autoreset_mode!r}") from None
        if autoreset_mode == AutoresetMode.DISABLED:
            raise ValueError("autoreset_mode must be 'NextStep' or 'SameStep', got 'Disabled'")
        if kwargs.get("render_mode") is not None:
            raise ValueError("the vector environment does not render; use render_mode=None "
                             "(render a single Scara-C11-v0 instead)")
        self.template = ScaraEnv(**kwargs)
        template = self.template
        self.num_envs = int(num_envs)
        self.max_episode_steps = int(max_episode_steps)
        self.metadata = {**type(self).metadata, "autoreset_mode": autoreset_mode}
        self.autoreset_mode = autoreset_mode
        self.render_mode = None
        self.single_action_space = template.action_space
        self.single_observation_space = template.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

        n = self.num_envs
        sim = template.sim
        self.control_dt = template.control_dt
        self._config = sim.config
        self._spec = template._spec
        self._bounds = template._bounds
        self.x = np.zeros((n, L.N_STATE))
        self.t = np.zeros(n)
        self.p = np.tile(template._p, (n, 1))
        self.command = np.zeros((n, 3))
        self.modes = np.zeros((n, L.N_MODES), dtype=np.int64)
        self.step_state = np.zeros((n, 2))
        self.counters = np.zeros((n, L.N_COUNTERS), dtype=np.int64)
        events = sim.ev_t.shape[0]
        self.ev_t = np.zeros((n, events))
        self.ev_code = np.zeros((n, events), dtype=np.int64)
        self.ev_axis = np.zeros((n, events), dtype=np.int64)
        self.result = np.zeros((n, N_RESULT))
        self.distance = np.zeros(n)
        self.obs = np.zeros((n, N_OBS), dtype=np.float32)
        self.steps = np.zeros(n, dtype=np.int64)
        self.collisions = np.zeros(n, dtype=np.int64)
        self.targets = np.zeros((n, 3))
        self._rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(n)]
        self._prev_done = np.zeros(n, dtype=bool)

    # -- episodes ----------------------------------------------------------------------
    def _reset_robot(self, i: int, options: dict | None = None) -> None:
        template = self.template
        start, target = template.episode_start(self._rngs[i], options)
        self.targets[i] = target
        self.p[i, L.TARGET:L.TARGET + 3] = target
        self.x[i] = 0.0
        self.x[i, :3] = start
        self.t[i] = 0.0
        self.command[i] = target if template.control_mode == "pd" else 0.0
        self.steps[i] = 0
        self.collisions[i] = 0
        self.distance[i] = start_episode(
            self.x[i], self.p[i], self.command[i], self._config, self.modes[i], self.step_state[i],
            self.counters[i], self._spec, self._bounds, self.obs[i], self.result[i])

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed must be an int, None or a list of {self.num_envs} seeds, "
                                 f"got {len(seeds)}")
        for i, s in enumerate(seeds):
            if s is not None:
                self._rngs[i] = seeding.np_random(s)[0]
        for i in range(self.num_envs):
            self._reset_robot(i, options)
        self._prev_done[:] = False
        return self.obs.copy(), {"target": self.targets.copy()}

    # -- stepping ----------------------------------------------------------------------
    def step(self, actions):
        a = check_actions(actions, (self.num_envs, 3))
        resetting = self._prev_done.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        for i in np.flatnonzero(resetting):
            self._reset_robot(i)
        active = ~resetting
        robot_step_batch(
            active, a, self.x, self.t, self.p, self.command, self._config, self.modes,
            self.step_state, self._spec, self._bounds, self.distance, self.ev_t, self.ev_code,
            self.ev_axis, self.counters, self.result, self.obs)
        result = self.result
        failed = active & (result[:, R_STATUS] < 0)
        if failed.any():
            i = int(np.flatnonzero(failed)[0])
            raise RuntimeError(f"integration failed in sub-environment {i} at t = {self.t[i]:.6f} s")
        reached = active & (result[:, R_REACHED] == 1.0)
        collided = active & (result[:, R_COLLISIONS] > 0)
        self.collisions[active] += result[active, R_COLLISIONS].astype(np.int64)
        self.steps[active] += 1
        terminated = reached | (collided & (self.template.collision_mode == "terminate"))
        truncated = active & (self.steps >= self.max_episode_steps)
        reward = np.where(active, result[:, R_REWARD], 0.0)
        info = {
            "is_success": reached,
            "cost": collided.astype(np.float64),
            "collision": collided,
            "collisions": self.collisions.copy(),
            "critical": self.modes[:, L.M_CRITICAL] == 1,
            "time": self.t.copy(),
            "energy": self.x[:, L.ENERGY].copy(),
            "clipped_actions": np.where(active, result[:, R_CLIPPED], 0).astype(np.int64),
            "reward_terms": {name: np.where(active, result[:, R_TERMS + k], 0.0)
                             for k, name in enumerate(REWARD_TERMS)},
            "reach_time": np.where(reached, result[:, R_REACH_TIME], np.nan),
            "_reach_time": reached,
        }
        done = terminated | truncated
        obs = self.obs.copy()
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            info["final_obs"] = np.where(done[:, None], obs, 0.0).astype(np.float32)
            info["_final_obs"] = done
            info["final_info"] = {k: v for k, v in info.items() if not k.startswith("final")}
            info["_final_info"] = done
            for i in np.flatnonzero(done):
                self._reset_robot(i)
            obs = self.obs.copy()
        self._prev_done = done
        return obs, reward, terminated, truncated, info

    def close_extras(self, **kwargs) -> None:
        self.template.close()
