"""Scara-C11-Goal-v0: the C11 move as a goal-conditioned task (the Gymnasium-Robotics goal API).

The goal is the joint target q^; the achieved goal is q. Rewards and episode ends are
functions of (achieved_goal, desired_goal, info), so that hindsight relabeling (SB3's
``HerReplayBuffer``) can recompute them for other goals. The physics, the wall and the
located events are ScaraEnv's.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from scara_gym.envs.config import EnvConfig, arguments_markdown
from scara_gym.envs.core import DISTANCE_SCALE
from scara_gym.envs.cuda_vector import ScaraCudaVectorEnv
from scara_gym.envs.scara_env import ScaraEnv
from scara_gym.envs.task import OBSERVATION_LAYOUT, OBSERVATION_NAMES
from scara_gym.envs.vector import ScaraVectorEnv
from scara_gym.model import checks

REWARD_TYPES = ("sparse", "dense", "mixed")
GOAL_CONFIG = EnvConfig(randomize_target=True)
"""the goal envs' configuration before their config and overrides: goals drawn per episode"""
GOAL_SLACK = 1e-6
MAX_GOAL_TOLERANCE = 1.0  # [rad and m]
"""[rad or m] added to acc in the goal test: covers the float32 rounding of the goals, so
that the located C11 event (all |q_i - q^_i| < acc) always passes the test on the goals"""
# the goal-free observation: the target error would tie it to the goal HER replaces
KEPT = np.array([i for i, name in enumerate(OBSERVATION_NAMES) if not name.startswith("target_error")])
GOAL_OBSERVATION_NAMES = tuple(OBSERVATION_NAMES[i] for i in KEPT)
Q = OBSERVATION_LAYOUT["q"]


def _costs(info, batch: int | None) -> np.ndarray | float:
    """info["cost"] of one info dict, a sequence or array of them (SB3's replay buffer), or a
    dict of arrays (the vector env); None or {}: no collision.
    """
    if info is None or (isinstance(info, Mapping) and not info):
        return 0.0 if batch is None else np.zeros(batch)
    missing = ("info must hold 'cost' (the step's collision cost) for the collision term; with SB3's "
               "HerReplayBuffer pass replay_buffer_kwargs={'copy_info_dict': True}")
    if isinstance(info, Mapping):
        if "cost" not in info:
            raise KeyError(missing)
        cost = np.asarray(info["cost"], dtype=np.float64)
    else:
        items = np.asarray(info, dtype=object)
        if not all(isinstance(item, Mapping) and "cost" in item for item in items.ravel()):
            raise KeyError(missing)
        cost = np.array([item["cost"] for item in items.ravel()], dtype=np.float64).reshape(items.shape)
    return float(cost) if batch is None and cost.ndim == 0 else cost


def _goals(achieved_goal, desired_goal) -> tuple[np.ndarray, np.ndarray]:
    """The goals as float64 arrays, checked: real numbers of one shape (..., 3) [rad, rad, m], finite."""
    if np.iscomplexobj(achieved_goal) or np.iscomplexobj(desired_goal):  # a cast would drop the imaginary part
        raise ValueError("achieved_goal and desired_goal must be arrays of real numbers of shape (..., 3) "
                         "[rad, rad, m], got complex ones")
    try:
        achieved = np.asarray(achieved_goal, dtype=np.float64)
        desired = np.asarray(desired_goal, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("achieved_goal and desired_goal must be arrays of numbers of shape (..., 3) "
                         "[rad, rad, m]") from None
    if achieved.shape != desired.shape or achieved.ndim == 0 or achieved.shape[-1] != 3:
        raise ValueError(f"achieved_goal and desired_goal must have one shape (..., 3) [rad, rad, m], got "
                         f"{achieved.shape} and {desired.shape}")
    for name, goal in (("achieved_goal", achieved), ("desired_goal", desired)):
        if not np.all(np.isfinite(goal)):
            raise ValueError(f"{name} must be finite [rad, rad, m]; it holds NaN or inf")
    return achieved, desired


class GoalOutcome(NamedTuple):
    """What the goals and the info make of one step (or a batch of them)."""

    terms: dict
    """the named reward terms: goal and collision"""
    reward: np.ndarray
    success: np.ndarray
    terminated: np.ndarray


class GoalRules:
    """Reward, success and episode end of the goal task as functions of the goals (batched)."""

    def __init__(self, reward_type: str, collision_penalty: float, accuracy: float, collision_mode: str,
                 goal_tolerance: float | None = None) -> None:
        self.reward_type = checks.choice("reward_type", reward_type, REWARD_TYPES)
        self.collision_penalty = checks.real("collision_penalty", collision_penalty, 0.0, 1e6)
        self.tolerance = accuracy if goal_tolerance is None else checks.real(
            "goal_tolerance", goal_tolerance, accuracy, MAX_GOAL_TOLERANCE,
            unit="rad and m, at least the task's accuracy acc")
        self.threshold = self.tolerance + GOAL_SLACK
        self.terminate_on_collision = collision_mode == "terminate"

    def outcome(self, achieved_goal, desired_goal, info) -> GoalOutcome:
        """Goals of shape (..., 3) give arrays of shape (...)."""
        achieved, desired = _goals(achieved_goal, desired_goal)
        cost = _costs(info, None if achieved.ndim == 1 else achieved.shape[0])
        if np.shape(cost) != achieved.shape[:-1]:
            raise ValueError(f"info: one step's info per pair of goals, {achieved.shape[:-1] or 'one'}; got info for "
                             f"{np.shape(cost) or 'one step'}")
        if not np.all(np.isfinite(cost)) or np.any(np.asarray(cost) < 0):
            raise ValueError("info['cost'] must be finite numbers >= 0 (the step's collision cost)")
        success = np.abs(achieved - desired).max(axis=-1) < self.threshold
        steps = -(~success).astype(np.float64)
        distance = -np.linalg.norm((achieved - desired) / DISTANCE_SCALE, axis=-1)
        goal = {"sparse": steps, "dense": distance, "mixed": steps + distance}[self.reward_type]
        terms = {"goal": goal, "collision": -self.collision_penalty * cost}
        terminated = success | (np.asarray(cost) > 0) if self.terminate_on_collision else success
        return GoalOutcome(terms, terms["goal"] + terms["collision"], success, terminated)


def _scalar(value):
    """A 0-d result as a Python scalar (one transition), arrays as they are (a batch)."""
    return value.item() if np.ndim(value) == 0 else value


class _GoalAPI:
    """compute_reward, compute_terminated, compute_truncated from ``self.rules`` (batched)."""

    rules: GoalRules

    def compute_reward(self, achieved_goal, desired_goal, info):
        """The step reward for (batches of) goals: shape (...,) for goals of shape (..., 3)."""
        return _scalar(self.rules.outcome(achieved_goal, desired_goal, info).reward)

    def compute_terminated(self, achieved_goal, desired_goal, info):
        return _scalar(self.rules.outcome(achieved_goal, desired_goal, info).terminated)

    def compute_truncated(self, achieved_goal, desired_goal, info):
        """False for every transition: only the time limit truncates."""
        achieved, _ = _goals(achieved_goal, desired_goal)
        return _scalar(np.zeros(achieved.shape[:-1], dtype=bool))


def _goal_spaces(task) -> spaces.Dict:
    low, high = task.obs_low, task.obs_high
    goal = spaces.Box(low[Q], high[Q], dtype=np.float32)
    return spaces.Dict({
        "observation": spaces.Box(low[KEPT], high[KEPT], dtype=np.float32),
        "achieved_goal": goal,
        "desired_goal": goal,
    })


class ScaraGoalEnv(_GoalAPI, ScaraEnv):
    """Scara-C11-Goal-v1: reach a goal configuration fast without hitting the wall (goal API).

    The C11 robot, wall and physics of Scara-C11-v2 with the Gymnasium-Robotics goal
    interface: the goal is the joint target q^ (drawn per episode by default), the achieved
    goal is q, and reward, success and episode end are functions of (achieved_goal,
    desired_goal, info) so that hindsight experience replay can relabel goals
    (``compute_reward``, ``compute_terminated``, ``compute_truncated``, batched).

    ## Action space

    ``Box(-1, 1, (3,), float32)``, as Scara-C11-v2: in "pd" mode (the default) a PD
    set-point (q^1 = a0 * pi rad, q^2 = a1 * pi rad, q^3 = 0.2 + 0.2 a2 m), in "voltage"
    mode armature voltages a_i * limit_i.

    ## Observation space

    ``Dict`` of three float32 Boxes:

    | key | shape | content |
    |---|---|---|
    | observation | (15,) | ScaraEnv's observation without target_error1..3 |
    | achieved_goal | (3,) | q = (q1, q2, q3) [rad, rad, m] |
    | desired_goal | (3,) | the target q^ [rad, rad, m] |

    "observation" holds q1, q2, q3, q1_rate, q2_rate, q3_rate, current1, current2,
    current3, tip_x, tip_y, wall_distance, height_margin, critical, time_left, with
    ScaraEnv's units and bounds (the target error is left out: it would tie the
    observation to the goal hindsight relabeling replaces). Observation noise, where
    configured, applies to "observation" only; the goals are exact (float32).

    ## Reward

    The sum of two named terms (in ``info["reward_terms"]``), from the goals and the info:

    | reward_type | goal term |
    |---|---|
    | sparse | -1 per step until the goal is reached, 0 on reaching it |
    | dense | -\\|\\|(q - q^) / (1 rad, 1 rad, 0.1 m)\\|\\| after the step |
    | mixed | the sum of the two (sparse + dense) |

    collision term: -collision_penalty x ``info["cost"]`` (1 in a step in which the tip hit
    the wall). ``compute_reward(achieved_goal, desired_goal, info)`` gives the same over a
    batch (info: one dict, a sequence or array of dicts, or a dict of arrays; None: no
    collisions).

    ## Starting state

    q = ``start`` (default (0, 0, 0)) at rest. The goal is drawn per episode as
    ScaraEnv's ``randomize_target`` draws it: q^1, q^2 in [1.5, 2.5] rad, q^3 in
    [0.2, 0.35] m, beyond the wall and above it; ``randomize_target=False`` keeps the C11
    target (2, 2, 0.3); ``reset(options={"target": ...})`` sets it for one episode.

    ## Episode end

    - terminated: the goal is reached: max_i |achieved_i - desired_i| < tol + 1e-6 on the
      goals (tol = ``goal_tolerance``, by default the C11 accuracy acc = 0.001; the slack
      covers float32 rounding, so that the C11 event located inside the step always passes),
      or a collision with ``collision="terminate"``;
      ``compute_terminated`` gives the same over a batch.
    - truncated: only by the time limit, ``max_episode_steps=300`` (3 s) as registered;
      ``compute_truncated`` is False for every transition.

    ## Info

    ScaraEnv's step info (cost, collision, collisions, critical, time, energy, ...) with
    ``is_success`` from the goal test and ``reward_terms`` holding the two terms above.

    ## Arguments

    - reward_type ("sparse"): "sparse", "dense" or "mixed", see the reward.
    - collision_penalty (50.0): the collision term's weight, in [0, 1e6]; with
      collision="terminate" a collision ends the episode, so the penalty must outweigh
      the sparse reward's steps it saves for a collision not to pay.
    - goal_tolerance (None): tol of the goal test [rad for q1, q2; m for q3], in
      [acc, 1]; None: acc = 0.001, the C11 task. A looser goal (Gymnasium-Robotics'
      distance_threshold) makes an easier task, e.g. for a curriculum.
    - config (None): an `EnvConfig` (default: ``GOAL_CONFIG``,
      the latest id's arguments with goals drawn per episode); every field of it can be
      given as a keyword, over it:
{ARGUMENTS}

    ## Version history

    - v1: the goal API on the latest id's integration (Scara-C11-v2: ``exact_switches=True``,
      ``rtol=1e-7``, ``atol=1e-9``), goals drawn per episode (``randomize_target=True``); the
      class defaults.
    - v0: first release: the goal API on Scara-C11-v1's physics (``exact_switches=True``,
      ``rtol=1e-6``, ``atol=1e-8``) with goals drawn per episode (``randomize_target=True``).
      Later added, without a change to what existing arguments do: ``reward_type="mixed"``,
      ``sensor_noise``, ``randomize_start``.
    """

    observation_names = GOAL_OBSERVATION_NAMES
    config_defaults = GOAL_CONFIG

    def __init__(self, reward_type: str = "sparse", collision_penalty: float = 50.0,
                 goal_tolerance: float | None = None, config: EnvConfig | None = None, *,
                 render_mode: str | None = None, **overrides) -> None:
        super().__init__(config, render_mode=render_mode, **overrides)
        self.rules = GoalRules(reward_type, collision_penalty, self.params.task.accuracy, self.collision_mode,
                               goal_tolerance)
        self.observation_space = _goal_spaces(self._task)

    reward_type = property(lambda self: self.rules.reward_type)

    def _goal_obs(self, obs: np.ndarray) -> dict:
        task = self._task
        return {"observation": obs[KEPT], "achieved_goal": task.obs[0][Q].copy(),
                "desired_goal": task.robot_params["target"][0].astype(np.float32)}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = super().reset(seed=seed, options=options)
        return self._goal_obs(obs), info

    def step(self, action):
        obs, _, _, _, info = super().step(action)
        goal_obs = self._goal_obs(obs)
        outcome = self.rules.outcome(goal_obs["achieved_goal"], goal_obs["desired_goal"], info)
        info["reward_terms"] = {name: float(value) for name, value in outcome.terms.items()}
        info["is_success"] = bool(outcome.success)
        terminated = bool(outcome.terminated)
        self._needs_reset = terminated
        return goal_obs, float(outcome.reward), terminated, False, info


ScaraGoalEnv.__doc__ = ScaraGoalEnv.__doc__.replace("{ARGUMENTS}", arguments_markdown(
    GOAL_CONFIG, (("render_mode", None, '"rgb_array" or "human", as ScaraEnv.'),), indent="    "))


class ScaraGoalVectorEnv(_GoalAPI, ScaraVectorEnv):
    """N copies of Scara-C11-Goal-v1 stepped in parallel (ScaraVectorEnv's arguments plus
    reward_type, collision_penalty and goal_tolerance). Observations are a dict of batched arrays; with
    ``autoreset_mode="SameStep"`` ``info["final_obs"]`` is such a dict too (zero for the
    robots that did not end). Robot i is the single env seeded seed + i.
    """

    def __init__(self, num_envs: int = 1, max_episode_steps: int = 300,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP, num_threads: int | None = None,
                 reward_type: str = "sparse", collision_penalty: float = 50.0, goal_tolerance: float | None = None,
                 config: EnvConfig | None = None, **kwargs) -> None:
        super().__init__(num_envs, max_episode_steps, autoreset_mode, num_threads, config, **kwargs)
        self.rules = GoalRules(reward_type, collision_penalty, self._task.params.task.accuracy,
                               self._task.collision_mode, goal_tolerance)
        self.single_observation_space = _goal_spaces(self._task)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

    def _agent_view(self, obs: np.ndarray) -> dict:
        task = self._task
        return {"observation": obs[:, KEPT], "achieved_goal": task.obs[:, Q].copy(),
                "desired_goal": task.robot_params["target"].astype(np.float32)}

    def _judge(self, reward, terminated, info, resetting):
        outcome = self.rules.outcome(self._task.obs[:, Q], self._task.robot_params["target"].astype(np.float32), info)
        stepped = ~resetting  # a robot reset in this step (NextStep) gets reward 0 and goes on
        terms = {name: np.where(stepped, value, 0.0) for name, value in outcome.terms.items()}
        info["reward_terms"] = terms
        info["is_success"] = outcome.success & stepped
        return terms["goal"] + terms["collision"], outcome.terminated & stepped, info


def make_goal_vector_env(num_envs: int = 1, device: str = "cpu", **kwargs):
    """The vector entry point of Scara-C11-Goal-v0: ``device="cpu"`` (default) gives
    `ScaraGoalVectorEnv`, ``device="cuda"`` `ScaraCudaGoalVectorEnv`.
    """
    if checks.choice("device", device, ("cpu", "cuda")) == "cuda":
        return ScaraCudaGoalVectorEnv(num_envs=num_envs, **kwargs)
    return ScaraGoalVectorEnv(num_envs=num_envs, **kwargs)


class ScaraCudaGoalVectorEnv(_GoalAPI, ScaraCudaVectorEnv):
    """Scara-C11-Goal-v0 on the GPU: N robots of ScaraGoalVectorEnv stepped by the CUDA
    backend (ScaraCudaVectorEnv's arguments plus reward_type, collision_penalty and
    goal_tolerance). Observations are a dict of tensors, rewards, flags and info tensors; robot i is
    ScaraGoalVectorEnv's robot i bit for bit on numba's CUDA simulator. The goal test
    ends episodes inside the step kernel (core.vector_robot_step's goal_threshold);
    rewards and terms are the goal rules on tensors. compute_reward and friends take
    numpy arrays (HER's replay buffers), as on the CPU.
    """

    def __init__(self, num_envs: int = 1, max_episode_steps: int = 300,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 reward_type: str = "sparse", collision_penalty: float = 50.0, goal_tolerance: float | None = None,
                 config: EnvConfig | None = None, **kwargs) -> None:
        super().__init__(num_envs, max_episode_steps, autoreset_mode, config=config, **kwargs)
        self.rules = GoalRules(reward_type, collision_penalty, self._task.params.task.accuracy,
                               self._task.collision_mode, goal_tolerance)
        self._goal_threshold = self.rules.threshold
        self._scale = self._torch.from_numpy(DISTANCE_SCALE).to(self.device)
        self.single_observation_space = _goal_spaces(self._task)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)

    def _agent_view(self, obs, clean_obs, targets):
        return {"observation": obs[:, KEPT], "achieved_goal": clean_obs[:, Q].clone(),
                "desired_goal": targets.to(self._torch.float32)}

    def _judge(self, clean_obs, targets, info, stepped):
        """GoalRules.outcome on tensors, in numpy's order of operations."""
        torch = self._torch
        gap = clean_obs[:, Q].to(torch.float64) - targets.to(torch.float32).to(torch.float64)
        success = gap.abs().amax(dim=1) < self.rules.threshold
        steps = -(~success).to(torch.float64)
        x = gap / self._scale  # np.linalg.norm's sum: (x0^2 + x1^2) + x2^2
        distance = -_sqrt(torch, (x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1]) + x[:, 2] * x[:, 2])
        goal = {"sparse": steps, "dense": distance, "mixed": steps + distance}[self.rules.reward_type]
        collision = -self.rules.collision_penalty * info["cost"]
        zero = torch.zeros_like(goal)
        terms = {"goal": torch.where(stepped, goal, zero), "collision": torch.where(stepped, collision, zero)}
        info["reward_terms"] = terms
        info["is_success"] = success & stepped
        return terms["goal"] + terms["collision"], info


def _sqrt(torch, values):
    """Correctly rounded square roots: torch's float64 sqrt on the CPU is not (about 1 % of
    values differ from numpy's in the last bit), CUDA's is.
    """
    if values.device.type == "cpu":
        return torch.from_numpy(np.sqrt(values.numpy()))
    return torch.sqrt(values)
