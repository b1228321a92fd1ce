"""scara_gym: the ARGESIM C11 SCARA robot benchmark as an exact model and Gymnasium environments."""

from scara_gym.params import (
    DEFAULT_PARAMS, ArmParams, AxisParams, ObstacleParams, ScaraParams, TaskParams,
)
from scara_gym.simulation import Event, Simulator, Trajectory
from scara_gym.tasks import compare_forms, obstacle_avoidance, point_to_point

__version__ = "0.1.0"

__all__ = [
    "ArmParams", "AxisParams", "DEFAULT_PARAMS", "Event", "ObstacleParams", "ScaraParams",
    "Simulator", "TaskParams", "Trajectory", "compare_forms", "obstacle_avoidance",
    "point_to_point",
]
