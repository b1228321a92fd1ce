"""scara_gym: the ARGESIM C11 SCARA robot benchmark as an exact model and Gymnasium environments.

Layout: `scara_gym.model` (the physics: numpy + numba), `scara_gym.envs` (the
task object, the compiled environment step, the single and vector environments, the
renderer, the vector-env factory), `scara_gym.wrappers` (what sits between an agent and
the env: the residual set-point and the model-predictive shield), `scara_gym.benchmark`
(the seed paper's tasks, the scipy reference, ``scara-c11 reproduce`` and ``bench``),
`scara_gym.integrations` (stable-baselines3) and `scara_gym.registration` (the ids).
Nothing here imports the ``agents`` package.
"""

from scara_gym.benchmark.tasks import compare_forms, obstacle_avoidance, point_to_point
from scara_gym.model import (
    DEFAULT_PARAMS,
    ArmParams,
    AxisParams,
    Event,
    ObstacleParams,
    ScaraParams,
    SimulationError,
    Simulator,
    TaskParams,
    Trajectory,
)
from scara_gym.registration import (
    ENV_IDS,
    ENV_KWARGS,
    ENV_VARIANTS,
    ENV_VERSIONS,
    GOAL_ENV_IDS,
    LATEST_ENV_ID,
    LATEST_IDS,
    LATEST_INTEGRATION,
    register_all,
)

__version__ = "0.4.0"

register_all()

__all__ = [
    "ENV_IDS", "ENV_KWARGS", "GOAL_ENV_IDS", "ENV_VARIANTS", "ENV_VERSIONS", "LATEST_ENV_ID", "LATEST_IDS",
    "LATEST_INTEGRATION",
    "__version__",
    "ArmParams", "AxisParams", "DEFAULT_PARAMS", "Event", "ObstacleParams", "ScaraParams",
    "SimulationError", "Simulator", "TaskParams", "Trajectory", "compare_forms", "obstacle_avoidance",
    "point_to_point",
]
