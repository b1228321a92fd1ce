"""The optimal reference as a policy: the held minimum-time actions replayed in the environment,
and the reference's replay as states (for reset initialization) and demonstrations."""

from __future__ import annotations

import time
from dataclasses import asdict

import gymnasium as gym
import numpy as np

from agents.policies.optimal.solutions import cached_solution, params_key
from agents.policies.optimal.transcription import CollocationConfig, minimum_time
from scara_gym import DEFAULT_PARAMS, ScaraParams
from scara_gym.benchmark.episodes import run_episode
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.envs import OBSERVATION_LAYOUT
from scara_gym.model.checks import UserError, UserKeyError

Q = OBSERVATION_LAYOUT["q"]


class OptimalPolicy:
    """Replays the held minimum-time actions in a "voltage"-mode environment.

    The actions of the shipped solution (C11 start and target, default parameters) are
    package data; for another start, target or parameter set, ``minimum_time`` solves the
    problem (CasADi needed) when the episode starts. Steps beyond the planned ones (which a
    faithful replay never reaches) command the C11 PD law towards the target."""

    name = "optimal"

    def __init__(self, env, solve_missing: bool = True) -> None:
        self.env = env.unwrapped
        if self.env.control_mode != "voltage":
            raise UserError("the optimal reference commands voltages: it needs control_mode='voltage', "
                            f"the environment is in {self.env.control_mode!r} mode")
        self.solve_missing = solve_missing
        self.plans: dict[tuple, np.ndarray] = {}
        self.actions = None
        self.step_index = 0

    def reset(self) -> None:
        self.actions = None
        self.step_index = 0

    @staticmethod
    def plan_key(start, target) -> tuple:
        """The key of ``plans`` for an episode from start to target."""
        return tuple(np.round(np.concatenate([start, target]), 12))

    def plan(self, start, target) -> np.ndarray:
        key = self.plan_key(start, target)
        if key not in self.plans:
            params = self.env.params
            data = cached_solution(start, target, params)
            if data is not None:
                self.plans[key] = np.array(data["held"]["actions"])
            elif self.solve_missing:
                self.plans[key] = minimum_time("held", start, target, params).actions
            else:
                raise UserKeyError(f"no shipped minimum-time solution from {list(start)} to {list(target)}")
        return self.plans[key]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=float)
        target = obs[Q] + obs[OBSERVATION_LAYOUT["target_error"]]
        if self.actions is None:  # the first observation of the episode: the start
            self.actions = self.plan(obs[Q].astype(float).round(6), target.round(6))
        k = self.step_index
        self.step_index += 1
        if k < len(self.actions):
            return np.clip(self.actions[k], -1.0, 1.0)
        return self.env.pd_action(obs, target)


def replaying(actions: np.ndarray, env_id: str, start, target, params: ScaraParams):
    """A "voltage"-mode environment from start to target and an OptimalPolicy in it that
    replays ``actions``."""
    env = gym.make(env_id, control_mode="voltage", params=params, start=tuple(start), target=tuple(target))
    policy = OptimalPolicy(env)
    policy.plans[OptimalPolicy.plan_key(start, target)] = np.asarray(actions)
    return env, policy


def replay(actions: np.ndarray, env_id: str = ENV_ID, start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
           params: ScaraParams = DEFAULT_PARAMS) -> dict:
    """Held actions run in the environment ("voltage" mode); the episode summary of
    scara_gym.benchmark.episodes.run_episode (success, collisions, reach_time, energy, ...)."""
    return run_episode(*replaying(actions, env_id, start, target, params), seed=0)


def _reference_replay(env_id: str, start, target, params: ScaraParams, wall_margin: float):
    """The shipped solution with this wall margin replayed in the environment ("voltage" mode):
    (the observation before each control step, the held action taken there, the task's
    snapshot after each step but the last). Raises if there is no such solution or the replay
    does not reach the target without a collision."""
    data = cached_solution(start, target, params, wall_margin)
    if data is None:
        raise UserKeyError(f"no shipped minimum-time solution from {list(start)} to {list(target)} with wall margin "
                           f"{wall_margin} m (scara-agents optimal --wall-margin M --write FILE makes one)")
    env, policy = replaying(np.array(data["held"]["actions"]), env_id, start, target, params)
    obs, _ = env.reset(seed=0)
    policy.reset()
    observations, actions, snapshots = [], [], []
    while True:
        action = policy(obs)
        observations.append(np.asarray(obs, dtype=np.float64))
        actions.append(np.asarray(action, dtype=np.float64))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
        snapshots.append(env.unwrapped.snapshot())
    env.close()
    if not info["is_success"] or info["collisions"]:
        raise RuntimeError(f"the optimal reference from {list(start)} to {list(target)} does not reach the "
                           f"target without a collision in {env_id}")
    return observations, actions, snapshots


def reference_snapshots(env_id: str = ENV_ID, start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
                        params: ScaraParams = DEFAULT_PARAMS,
                        wall_margin: float = CollocationConfig.wall_margin) -> list[dict]:
    """The states the optimal reference (its shipped solution with this wall margin) passes
    through in the environment, one after each of its control steps before the last (the one
    that reaches the target), as ``ScaraEnv.snapshot`` gives them: starts for reference state
    initialization (the torch PPO's ``demo_resets`` hook). Raises if the replay does not reach
    the target."""
    return _reference_replay(env_id, start, target, params, wall_margin)[2]


def reference_demonstration(env_id: str = ENV_ID, start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
                            params: ScaraParams = DEFAULT_PARAMS,
                            wall_margin: float = CollocationConfig.wall_margin) -> tuple[np.ndarray, np.ndarray]:
    """(observations, actions) of the optimal reference's replay in the environment ("voltage"
    mode): the observation before each of its control steps and the held action it takes
    there, as float64 arrays (steps, 18) and (steps, 3). Demonstrations for behaviour cloning
    (the torch PPO's ``demo_bc`` hook). Raises if the replay does not reach the target."""
    observations, actions, _ = _reference_replay(env_id, start, target, params, wall_margin)
    return np.array(observations), np.array(actions)


def solve_reference(start, target, params: ScaraParams = DEFAULT_PARAMS, wall_margin: float = CollocationConfig.wall_margin,
                    verbose: bool = False) -> dict:
    """Both minimum-time problems from ``start`` to ``target`` (the free one without margins: the
    continuous-time bound; the held one with ``wall_margin``), the held solution replayed in the
    environment: the record a shipped solution file holds (without its condition and command)."""
    config = CollocationConfig(wall_margin=wall_margin)
    bound_config = CollocationConfig(wall_margin=0.0, band_margin=0.0)
    started = time.perf_counter()
    free = minimum_time("free", start, target, params, config=bound_config, verbose=verbose)
    print(f"free (the continuous-time bound, no margins): {free.time:.5f} s ({free.status}); critical from "
          f"{free.phase_times[0]:.4f} s, q3 at h_obs {free.phase_times[1]:.4f} s")
    held = minimum_time("held", start, target, params, config=config, verbose=verbose)
    result = replay(held.actions, start=start, target=target, params=params)
    print(f"held (0.01 s steps, margins {config.wall_margin} m / {config.band_margin}): {held.time:.5f} s in the "
          f"transcription ({held.status}); replayed in {ENV_ID}: success {result['success']}, collisions "
          f"{result['collisions']}, time {result['reach_time']:.5f} s, energy {result['energy']:.1f} J")
    return {"start": list(start), "target": list(target), "params": params_key(params),
            "config": asdict(config), "free": {**free.to_json(), "config": asdict(bound_config)}, "held": held.to_json(),
            "replay": {k: result[k] for k in ("success", "collisions", "reach_time", "energy", "steps")},
            "seconds": time.perf_counter() - started}
