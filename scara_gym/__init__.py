"""scara_gym: the ARGESIM C11 SCARA robot benchmark as an exact model and Gymnasium environments."""

from scara_gym.params import (
    DEFAULT_PARAMS, ArmParams, AxisParams, ObstacleParams, ScaraParams, TaskParams,
)
from scara_gym.simulation import Event, Simulator, Trajectory
from scara_gym.tasks import compare_forms, obstacle_avoidance, point_to_point

__version__ = "0.1.0"

from gymnasium.envs.registration import register, registry  # noqa: E402

ENV_ID = "Scara-C11-v0"
if ENV_ID not in registry:
    # 300 steps of the default 0.01 s control step: the 3 s time limit
    register(id=ENV_ID, entry_point="scara_gym.envs:ScaraEnv", max_episode_steps=300,
             vector_entry_point="scara_gym.envs.vector:ScaraVectorEnv")

__all__ = [
    "ENV_ID",
    "ArmParams", "AxisParams", "DEFAULT_PARAMS", "Event", "ObstacleParams", "ScaraParams",
    "Simulator", "TaskParams", "Trajectory", "compare_forms", "obstacle_avoidance",
    "point_to_point",
]
