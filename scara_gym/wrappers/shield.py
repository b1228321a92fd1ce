"""A model-predictive safety shield for any policy of the single environment.

A shield (Alshiekh et al. 2018) stands between a policy and the robot and replaces an action
only where it would lead to a collision. This one decides by prediction, as a predictive
safety filter does (Wabersich and Zeilinger 2021): before each step it copies the robot's
state into a model of the robot (the same compiled simulator, with the parameters the
shield was given), applies the policy's action there and then the backup policy until the
arm has come to rest. Where that rollout touches the wall, or the arm is still moving after
``horizon`` steps, the robot gets the backup's action instead of the policy's.

The backup is the ``dec`` heuristic's move without its trigger: hold axes 1 and 2 where they
are (the PD law brakes them, with the widened voltage near the wall) and drive axis 3 to its
target, at least ``climb_margin`` above the wall. It is a state feedback, so the rollout the
shield checked is the path the robot takes if the backup keeps acting; with an exact model
(the shield's parameters those of the episode) a policy behind the shield therefore never
collides from a state where the backup is safe, as at rest. With other parameters (the
nominal ones under a shifted robot: ``params``) the prediction is only as good as the model.

The shield reads the robot's full state from the environment (``ScaraTask.snapshot``),
not from the observation, and costs up to ``1 + horizon`` model steps per control step.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from scara_gym.envs.task import OBSERVATION_LAYOUT
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams
from scara_gym.registration import TRAINING_ENV_ID

Q, RATES, TARGET_ERROR = (OBSERVATION_LAYOUT[name] for name in ("q", "rate", "target_error"))


def hold_and_climb(held: np.ndarray, target: np.ndarray, lowest_height: float = -np.inf) -> np.ndarray:
    """The set-point that holds axes 1 and 2 at ``held`` [rad] and drives axis 3 to its target,
    at least ``lowest_height`` [m]: the braking move of the seed paper's obstacle rule (the
    ``dec`` heuristic's, and this shield's backup)."""
    return np.array([held[0], held[1], max(target[2], lowest_height)])


class Shield:
    """``policy``'s action where the model predicts that the backup can still stop the arm
    without a collision after it, else the backup's (module docstring). ``interventions``
    counts the steps of the current episode where the backup acted. ``env`` gives the model's
    environment arguments and, for ``__call__``, the robot; ``filter`` shields any task's robot
    (a vector environment's in training, shielded RL), with ``policy`` None."""

    def __init__(self, env, policy, params: ScaraParams | None = DEFAULT_PARAMS, horizon: int = 100,
                 rest_rate: float = 0.02, climb_margin: float = 0.01) -> None:
        self.env = env.unwrapped
        if self.env.task.actuator is not None:
            raise ValueError("Shield: the action_delay / action_rate_limit line has a state the model cannot copy")
        if not (isinstance(horizon, (int, np.integer)) and 1 <= horizon <= 1000):
            raise ValueError(f"horizon must be an integer in [1, 1000] control steps, got {horizon!r}")
        for name, value in (("rest_rate", rest_rate), ("climb_margin", climb_margin)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        self.policy = policy
        self.horizon, self.rest_rate, self.climb_margin = int(horizon), float(rest_rate), float(climb_margin)
        spec = self.env.spec
        kwargs = {**(spec.kwargs if spec is not None else {}), "control_mode": self.env.control_mode,
                  "randomize_target": False, "render_mode": None}
        kwargs.pop("randomize_params", None)
        if params is not None:
            kwargs["params"] = params
        self.model = gym.make(spec.id if spec is not None else TRAINING_ENV_ID, **kwargs).unwrapped
        self.model_task = self.model.task
        self.name = f"{getattr(policy, 'name', 'policy')} + shield"
        self.interventions = 0

    def reset(self) -> None:
        if self.policy is not None:
            self.policy.reset()
        self.interventions = 0

    def backup(self, obs: np.ndarray, task, index: int = 0) -> np.ndarray:
        """The backup's action on robot ``index``'s raw observation, for the environment of ``task``."""
        q = obs[Q].astype(float)
        height = task.episode_params[index].obstacle.height
        return task.setpoint_action(obs, hold_and_climb(q, q + obs[TARGET_ERROR], height + self.climb_margin))

    def safe(self, snapshot: dict, action: np.ndarray) -> bool:
        """Whether, from ``snapshot``, ``action`` and then the backup leave the wall untouched
        and bring axes 1 and 2 to rest within the horizon (or reach the target)."""
        task = self.model_task
        if not np.array_equal(task.robot_params["target"][0], snapshot["target"]):  # the model's episode's target
            self.model.reset(seed=0, options={"target": tuple(float(x) for x in snapshot["target"])})
        task.restore(0, {**snapshot, "params": task.episode_params[0]})
        outcome = task.outcomes[0]
        action = np.ascontiguousarray(action, dtype=np.float64)
        for _ in range(self.horizon + 1):
            task.step_robot(0, action)
            if outcome["collisions"] > 0:
                return False
            obs = task.obs[0]
            if outcome["reached"] or np.all(np.abs(obs[RATES][:2]) < self.rest_rate):
                return True
            action = np.ascontiguousarray(self.backup(obs.astype(np.float64), task))
        return False

    def filter(self, task, index: int, action: np.ndarray) -> tuple[np.ndarray, bool]:
        """(the action robot ``index`` of ``task`` gets, whether the backup replaced ``action``):
        the single environment's robot 0, or one robot of a vector environment's task."""
        action = np.asarray(action, dtype=np.float64)
        if self.safe(task.snapshot(index), action):
            return action, False
        return self.backup(task.obs[index].astype(np.float64), task, index), True

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        action, replaced = self.filter(self.env.task, 0, self.policy(obs))
        self.interventions += replaced
        return action
