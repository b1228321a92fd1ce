"""scara_gym: the ARGESIM C11 SCARA robot benchmark as an exact model and Gymnasium environments.

Layout: :mod:`scara_gym.model` (the physics: numpy + numba), :mod:`scara_gym.envs` (the
task object, the compiled environment step, the single and vector environments, the
renderer), :mod:`scara_gym.benchmark` (the seed paper's tasks, the scipy reference,
``scara-c11 reproduce`` and ``bench``), :mod:`scara_gym.integrations` (stable-baselines3).
"""

from scara_gym.model import (
    DEFAULT_PARAMS, ArmParams, AxisParams, Event, ObstacleParams, ScaraParams, SimulationError, Simulator,
    TaskParams, Trajectory,
)
from scara_gym.benchmark.tasks import compare_forms, obstacle_avoidance, point_to_point

__version__ = "0.2.0"

from gymnasium.envs.registration import register, registry  # noqa: E402

ENV_ID = "Scara-C11-v0"
ENV_IDS = (ENV_ID,)
"""Every environment id this package registers."""
if ENV_ID not in registry:
    # 300 steps of the default 0.01 s control step: the 3 s time limit
    register(id=ENV_ID, entry_point="scara_gym.envs:ScaraEnv", max_episode_steps=300,
             vector_entry_point="scara_gym.envs.vector:ScaraVectorEnv")

__all__ = [
    "ENV_ID", "ENV_IDS", "__version__",
    "ArmParams", "AxisParams", "DEFAULT_PARAMS", "Event", "ObstacleParams", "ScaraParams",
    "SimulationError", "Simulator", "TaskParams", "Trajectory", "compare_forms", "obstacle_avoidance",
    "point_to_point",
]
