"""The evaluation conditions and the one environment factory of the experiments."""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym

from scara_gym import DEFAULT_PARAMS
from scara_gym.registration import TRAINING_ENV_ID

_axes = DEFAULT_PARAMS.axes


@dataclass(frozen=True)
class Condition:
    """One evaluation condition: environment arguments and parameter overrides."""

    name: str
    description: str
    randomize_target: bool = False
    params: dict = field(default_factory=dict)


CONDITIONS = {c.name: c for c in (
    Condition("c11", "the C11 target (2, 2, 0.3) with the wall"),
    Condition("random-targets", "targets drawn per episode beyond the wall", randomize_target=True),
    Condition("load-x2", "load mass x2 (m3L 0.5 -> 1.0 kg)", params={"arm.load_mass": 2 * DEFAULT_PARAMS.arm.load_mass}),
    Condition("wall-closer", "wall 2 cm closer to the arm's start (x_obs 0.35 -> 0.37 m)",
              params={"obstacle.x_position": DEFAULT_PARAMS.obstacle.x_position + 0.02}),
    Condition("current-limits-15", "current limits -15 %",
              params={f"axes.{i}.current_limit": 0.85 * a.current_limit for i, a in enumerate(_axes)}),
    Condition("resistance+20", "motor resistances +20 %",
              params={f"axes.{i}.resistance": 1.2 * a.resistance for i, a in enumerate(_axes)}),
)}
SHIFTS = ("load-x2", "wall-closer", "current-limits-15", "resistance+20")
"""the conditions that shift the robot's parameters (the robustness target's)"""

TASK_KWARGS = ("goal_tolerance",)
"""environment arguments that define the task a run trains for (not its reward or its physics):
an evaluation that uses a run's own reports them beside the benchmark's"""


def make_env(condition: Condition, control_mode: str, env_id: str = TRAINING_ENV_ID, **task):
    """The condition's environment; task: TASK_KWARGS to set (default: the benchmark's own)."""
    unknown = sorted(set(task) - set(TASK_KWARGS))
    if unknown:
        raise ValueError(f"task arguments must be among {TASK_KWARGS}, got {unknown}")
    return gym.make(env_id, control_mode=control_mode, randomize_target=condition.randomize_target,
                    params=DEFAULT_PARAMS.replace(condition.params), **task)
