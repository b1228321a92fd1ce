"""The Gymnasium environments: a task object, the compiled step, and thin adapters over them.

- :mod:`~scara_gym.envs.config`: :class:`EnvConfig`, every environment's one configuration;
- :mod:`~scara_gym.envs.task`: :class:`ScaraTask` (records, episodes, info from an EnvConfig),
  :class:`RewardWeights`, the observation layout and the set-point <-> action mapping;
- :mod:`~scara_gym.envs.core`: the compiled per-robot step;
- :mod:`~scara_gym.envs.randomization`: parameters drawn per episode (:class:`ParameterRanges`);
- :mod:`~scara_gym.envs.sim_to_real`: observation noise, actuation delay, action rate limit;
- :mod:`~scara_gym.envs.variants`, :mod:`~scara_gym.envs.goal`: the cards of the registered
  variants (randomized physics and wall: ScaraEnv with other arguments) and the goal-conditioned task;
- :mod:`~scara_gym.envs.scara_env`: :class:`ScaraEnv`, the env of every registered id;
- :mod:`~scara_gym.envs.vector`: :class:`ScaraVectorEnv`, the native vector environment;
- :mod:`~scara_gym.envs.rendering`: the matplotlib renderer.
"""

from scara_gym.envs.config import EnvConfig
from scara_gym.envs.randomization import PRESETS as RANDOMIZATION_PRESETS, ParameterRanges
from scara_gym.envs.scara_env import ScaraEnv
from scara_gym.envs.task import (
    OBSERVATION_LAYOUT,
    OBSERVATION_NAMES,
    REWARD_TERMS,
    RewardWeights,
    ScaraTask,
)

__all__ = ["EnvConfig", "OBSERVATION_LAYOUT", "OBSERVATION_NAMES", "RANDOMIZATION_PRESETS", "REWARD_TERMS", "ParameterRanges",
           "RewardWeights", "ScaraEnv", "ScaraTask"]
